"""A campaign as a JUnit XML report (``tli verify --junit FILE``), for CI test-report views.

One ``<testsuite>`` (in a ``<testsuites>`` root) per campaign; one ``<testcase>`` per run, in
generation order, named ``run N``:

* a run that violated a check has a ``<failure>`` (``type`` the primary violation kind,
  ``message`` the oracle's first message, the text every message, the modes, and -- for the
  run whose case was saved -- the ``tli replay`` command of the counterexample);
* a run without a violation whose reachability was not decided is ``<skipped>`` (it proves
  nothing, and violated nothing);
* the suite's ``<properties>`` record the seed, the task, the files and their SHA-256, and the
  settings, so the report names what ran.

The counts match the campaign record: ``tests`` = ``runs``, ``failures`` = ``violating_runs``.
"""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Any

from tli_verify.io import atomic_write_text

__all__ = ["junit_xml", "write_junit"]

_BAD_XML = re.compile("[\x00-\x08\x0b\x0c\x0e-\x1f\ufffe\uffff]")


def _clean(text: object) -> str:
    """Text XML 1.0 can hold (control characters dropped)."""
    return _BAD_XML.sub("", str(text))


def _properties(result: Any, counterexample: str | os.PathLike[str] | None
                ) -> list[tuple[str, str]]:
    c = result.config
    props: list[tuple[str, str]] = [
        ("task", result.task_name), ("seed", str(c.seed)), ("examples", str(c.examples)),
        ("modulation", "true" if c.modulation else "false"), ("backend", c.backend),
        ("batch_size", str(c.batch_size)), ("max_pushes", str(c.max_pushes)),
        ("window", str(c.window)), ("levels", ",".join(c.levels)),
        ("random_starts", str(c.random_starts).lower()), ("lag", str(c.lag)),
        ("partial", "true" if result.partial else "false"),
        ("inconclusive", str(result.inconclusive))]
    for name in ("task", "spec", "model", "certificate"):
        entry = result.files.get(name) or {}
        where = entry.get("path") or entry.get("entry_point")
        if where is not None:
            props.append((f"{name}.{'path' if 'path' in entry else 'entry_point'}",
                          str(where)))
        if entry.get("sha256"):
            props.append((f"{name}.sha256", str(entry["sha256"])))
    if result.failure_bound is not None:
        props.append(("failure_probability_bound_95", f"{result.failure_bound:.6g}"))
    if counterexample is not None:
        props.append(("counterexample", str(counterexample)))
    return props


def junit_xml(result: Any, *, counterexample: str | os.PathLike[str] | None = None) -> str:
    """The JUnit XML text of a campaign.

    Parameters
    ----------
    result : CampaignResult
        :func:`tli_verify.verify.campaign.run_campaign`'s result.
    counterexample : path-like, optional
        Where the campaign saved its (shrunk) counterexample case; its run's failure names the
        ``tli replay`` command.

    Returns
    -------
    str
        UTF-8 XML with a declaration, one ``<testsuite>``.
    """
    import shlex
    import xml.etree.ElementTree as ET

    c = result.config
    mode = "LTL-DS" if c.modulation else "no modulation"
    suite_name = f"tli verify: {result.task_name} ({mode}, seed {c.seed})"
    classname = f"tli-verify.{result.task_name}.{'ltlds' if c.modulation else 'no-modulation'}"
    outcomes = list(result.outcomes)
    failures = sum(1 for o in outcomes if not o.verdict.ok)
    skipped = sum(1 for o in outcomes if o.verdict.ok and not o.verdict.conclusive)
    counts = {"tests": str(len(outcomes)), "failures": str(failures), "errors": "0",
              "skipped": str(skipped), "time": f"{float(result.seconds):.3f}"}
    root = ET.Element("testsuites", {"name": "tli verify", **counts})
    suite = ET.SubElement(root, "testsuite", {"name": _clean(suite_name), **counts})
    props = ET.SubElement(suite, "properties")
    for name, value in _properties(result, counterexample):
        ET.SubElement(props, "property", {"name": name, "value": _clean(value)})
    ce = result.counterexample
    ce_index = ce.get("index") if isinstance(ce, dict) else None
    width = len(str(max(len(outcomes), 1)))
    for o in outcomes:
        v = o.verdict
        case = ET.SubElement(suite, "testcase", {
            "classname": _clean(classname), "name": f"run {o.index + 1:0{width}d}"})
        detail = (f"steps {o.steps}, cuts added {o.cuts_added}, modes {o.modes[:200]}, "
                  f"oracle modes {v.oracle_modes[:200]}, robustness {v.robustness:.4g}")
        if not v.ok:
            kind = v.primary.value if v.primary is not None else "violation"
            text = [f"{m.kind.value} (step {m.step}): {m.message}" for m in v.violations]
            text.append(detail)
            if ce_index is not None and ce_index == o.index and counterexample is not None:
                shrunk = "shrunk " if ce.get("shrunk") else ""
                text.append(f"the campaign's {shrunk}counterexample comes from this run: "
                            f"tli replay {shlex.quote(str(counterexample))}")
            fail = ET.SubElement(case, "failure", {
                "type": kind, "message": _clean(v.violations[0].message[:500])})
            fail.text = _clean("\n".join(text))
        elif not v.conclusive:
            why = ("a reading left the environment assumptions" if not v.assumptions_ok
                   else "the run ended before the certified deadline")
            ET.SubElement(case, "skipped", {"message": _clean(f"undecided: {why}")})
        out = ET.SubElement(case, "system-out")
        out.text = _clean(detail)
    ET.indent(root)
    return ('<?xml version="1.0" encoding="utf-8"?>\n'
            + ET.tostring(root, encoding="unicode") + "\n")


def write_junit(result: Any, path: str | os.PathLike[str], *,
                counterexample: str | os.PathLike[str] | None = None) -> Path:
    """Write :func:`junit_xml` to ``path`` atomically (:func:`tli_verify.io.atomic_write_text`;
    missing folders created)."""
    p = Path(path)
    atomic_write_text(p, junit_xml(result, counterexample=counterexample))
    return p
