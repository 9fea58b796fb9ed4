"""Motion commands: ``tli learn``, ``tli certify``, ``tli check-cert``, ``tli gate``.

Exit codes (``docs/design.md``): 0 success; 1 a check said no (not certifiable, certificate does not
re-check, gate blocked, solver status not optimal); 2 bad input or usage. ``--json`` prints one
JSON object per line on stdout.
"""

from __future__ import annotations

import argparse
import json
import sys
from fractions import Fraction
from pathlib import Path
from typing import Any

from tli_verify.commands import check_plan, float_range, int_range, output_path, positive_float
from tli_verify.demos import load_demo, load_pose_demo
from tli_verify.ds.lyapunov import RATE_BUDGET
from tli_verify.ds.quaternion import (
    ORIENTATION_MODEL_KIND,
    learn_quaternion_ds,
    write_orientation_model,
)
from tli_verify.errors import (
    CertificateError,
    DemoError,
    GateError,
    ModelError,
    TliError,
    bad_input,
)
from tli_verify.io import bundled_dir, check_output_file, read_json
from tli_verify.logic.spec import load_spec
from tli_verify.model.learn import learn_model
from tli_verify.model.serialize import load_model, save_model
from tli_verify.plotting import save_figure
from tli_verify.project import control_period
from tli_verify.runtime.handoff import context_for_spec, handoff_status, learn_handoffs
from tli_verify.tasks.project import model_files, pose_blocks, spec_state_names, spec_task

__all__ = ["demo_stage", "register"]


_positive_float = positive_float


_control_period = float_range(1e-6, 1.0, "s")
"""A control period: 1 microsecond to 1 s (a DS step of a robot loop; a subnormal or zero
period would make the sampled condition vacuous)."""
_margin = float_range(1e-9, 1e3)
"""An LMI margin ``eps``: 1e-9 (below it the SDP solver's own tolerance decides) to 1e3."""
_decay_rate = float_range(1e-6, 1e4, "1/s", zero=True)
"""A certified decay rate: 0 (margin only), or 1e-6 to 1e4 per second."""
_budget = float_range(1e-6, 100.0, zero=True)
"""``--rate-budget``: 0, or a relative RMSE increase of 1e-6 to 100."""


def _rational(text: str) -> Fraction:
    """A positive exact rational (``0.001``, ``1/200``) for ``--dt``."""
    from tli_verify.certification.exact import parse_rational

    try:
        value = parse_rational(text, what="--dt")
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    if value <= 0:
        raise argparse.ArgumentTypeError(f"--dt: {text!r} must be positive")
    if not Fraction(1, 10**6) <= value <= 1:
        raise argparse.ArgumentTypeError(f"must be between 1e-06 and 1 s, got {text!r}")
    return value


_seed = int_range(0, 2**32 - 1)
"""A seed: 0 to 2^32 - 1."""


def _rerun_examples(text: str) -> int:
    """``--rerun N``: examples of the gate's re-run campaign, 1 to 100,000 (the command always
    re-runs; only ``run_gate(rerun=0)`` in Python skips it, for tests of the other checks)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
    if not 1 <= value <= 100_000:
        raise argparse.ArgumentTypeError(f"must be between 1 and 100000 (the gate always "
                                         f"re-runs a sample), got {text!r}")
    return value


def _blocks(text: str) -> tuple[tuple[int, ...], ...]:
    """``--blocks``: ``none`` or groups of indices, ``;`` between groups, ``,`` within."""
    if text.strip().lower() == "none":
        return ()
    try:
        groups = tuple(tuple(int(c) for c in g.split(",")) for g in text.split(";"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected 'none' or groups of coordinate indices "
                                         f"like '3,5' or '0,1,2;3,4,5', got {text!r}") from None
    flat = [c for g in groups for c in g]
    if any(c < 0 or c > 99 for c in flat) or len(set(flat)) != len(flat):
        raise argparse.ArgumentTypeError(f"coordinates must be distinct indices 0 to 99, got "
                                         f"{text!r}")
    return groups


def _emit(obj: dict[str, Any]) -> None:
    sys.stdout.write(json.dumps(obj, sort_keys=True) + "\n")


def register(sub: argparse._SubParsersAction[Any]) -> None:
    """Register ``learn``, ``certify``, ``check-cert`` and ``gate``."""
    p = sub.add_parser(
        "learn", help="learn a Lyapunov-stable LPV-DS per mode from demonstration CSVs",
        description="Segment demonstrations into modes by their sensor columns (through the "
        "spec's [modes] labels with --spec), then learn one LPV-DS per mode (PC-GMM mixing, "
        "P-QLF and Lyapunov-constrained SDPs with Clarabel) and write the model JSON.")
    p.add_argument("demos", nargs="+", type=Path, metavar="DEMO.csv")
    p.add_argument("--spec", type=Path, default=None, help="spec TOML whose [modes] label "
                   "the sensor states")
    p.add_argument("-o", "--output", type=output_path, required=True, metavar="MODEL.json",
                   help="model file to write (must not be one of the inputs)")
    p.add_argument("--seed", type=_seed, default=0, help="clustering seed (default 0)")
    p.add_argument("--eps", type=_margin, default=1e-3,
                   help="LMI margin: A_k^T P + P A_k <= -eps I (default 1e-3; 1e-9 to 1e3)")
    rate = p.add_mutually_exclusive_group()
    rate.add_argument("--rate", type=_decay_rate, default=None,
                      help="force this certified decay rate of V on every DS, A_k^T P + "
                      "P A_k <= -rate P (1/s; 0: margin --eps only, the earlier margin-only "
                      "learner; else 1e-6 to 1e4; default: chosen per DS under --rate-budget)")
    rate.add_argument("--rate-budget", type=_budget, default=None, metavar="B",
                      help="per DS, fit at rate 0, then certify the largest rate on a "
                      "half-octave grid up to the data's mean |xdot| / mean |x - x*| whose "
                      "training velocity RMSE is within (1 + B) x the rate-0 fit's (default "
                      "0.03; 0 or 1e-6 to 100; recorded in the model's fit)")
    p.add_argument("--control-dt", type=_control_period, default=None, metavar="DT",
                   help="with a rate: V also decreases per explicit step of this period "
                   "(default: the control period of the spec's task, else 0.01 s; 1e-6 to "
                   "1 s)")
    p.add_argument("--baseline", action="store_true",
                   help="EM GMM with K by BIC and P = I instead of PC-GMM + P-QLF")
    p.add_argument("--blocks", type=_blocks, default=None, metavar="GROUPS",
                   help="groups of coordinates every A_k keeps decoupled: 'none' (every entry "
                   "free), or indices like '3,5' or '0,1,2;3,4,5' (entry (r, c) is 0 unless r "
                   "and c share a group; the rest form one more group); default: a pose "
                   "task's orientation coordinates (position and orientation decoupled), else "
                   "none; recorded as the fit's blocks")
    p.add_argument("--no-handoff", action="store_true",
                   help="skip the offline step: by default, where the spec's task declares its "
                   "regions, every mode's exits are found and cut before deployment and the "
                   "hand-off claims are recorded in the model (docs: explanation/handoff)")
    p.add_argument("--handoff-samples", type=int_range(10, 100_000), default=1000, metavar="N",
                   help="states drawn per DS in each round of the offline step (default 1000)")
    p.add_argument("--json", action="store_true", help="one JSON object per line")
    p.set_defaults(handler=_learn)

    p = sub.add_parser(
        "certify", help="exactly verify a model's Lyapunov conditions and write a certificate",
        description="For every mode, with the model's own P (the one the runtime uses): P > 0, "
        "A_k^T P + P A_k < 0, (I + dt A_k)^T P (I + dt A_k) < P at the control period and a "
        "certified decay rate, decided in exact rational arithmetic; writes the certificate "
        "JSON. Exit 1 naming the mode and condition when the model's P does not certify "
        "(--repair then writes a new model with a certifying P).")
    p.add_argument("model", type=Path, metavar="MODEL.json")
    p.add_argument("-o", "--output", type=output_path, default=None, metavar="CERT.json",
                   help="default: certificates/<name>.cert.json of the model's project (of the "
                   "repaired model with "
                   "--repair)")
    p.add_argument("--dt", type=_rational, default=None, metavar="SECONDS",
                   help="control period of the sampled-data conditions, exact (e.g. 0.001 or "
                   "1/200; default: the control period of the task the model's spec names, "
                   "else 1/100); the certificate also covers shorter periods")
    p.add_argument("--repair", type=output_path, default=None, metavar="NEW.model.json",
                   help="replace each P that does not certify by one found by an SDP (checked "
                   "exactly), write the new model there, and certify it")
    p.add_argument("--json", action="store_true", help="one JSON object per line")
    p.set_defaults(handler=_certify)

    p = sub.add_parser(
        "check-cert", help="re-check a certificate from its numbers and the file hashes",
        description="Recomputes the digest, the model (and spec) SHA-256, the model's P, the "
        "recorded eigenvalues and the exact rational Lyapunov check. Exit 1 saying what "
        "differs.")
    p.add_argument("certificate", type=Path, metavar="CERT.json")
    p.add_argument("--model", type=Path, default=None, metavar="MODEL.json",
                   help="check against this model file instead of the one the certificate names")
    p.add_argument("--json", action="store_true", help="one JSON object per line")
    p.set_defaults(handler=_check_cert)

    p = sub.add_parser(
        "learn-orientation", help="learn a certified orientation DS from pose demonstrations",
        description="Reads pose demonstration CSVs (time, x0.., q0..q3 with a '# quaternion: "
        "scalar-first|scalar-last' line), fixes hemisphere flips and normalises non-unit "
        "quaternions (reported), and learns an LPV-DS in the tangent space at the attractor "
        "q* (the mean last orientation), with its own Lyapunov matrix, the rate choice and "
        "the sampled-data constraint at --control-dt. Writes the orientation model JSON; "
        "certify it with tli certify.")
    p.add_argument("demos", nargs="+", type=Path, metavar="POSE.csv")
    p.add_argument("-o", "--output", type=output_path, required=True, metavar="OUT.json")
    p.add_argument("--seed", type=_seed, default=0, help="seed of the mixture (default 0)")
    p.add_argument("--control-dt", type=_control_period, default=None, metavar="SECONDS",
                   help="control period of the sampled-data constraint (default 0.01 s, the "
                   "one default; 1e-6 to 1 s)")
    p.add_argument("--json", action="store_true", help="one JSON object per line")
    p.set_defaults(handler=_learn_orientation)

    p = sub.add_parser(
        "gate", help="deployment gate: every certificate, model and spec re-checks",
        description="Exit 0 only when every certificate under DIR/certificates re-checks "
        "exactly, every model under DIR/models has a valid certificate and campaign evidence "
        "(DIR/certificates/NAME.campaign.json) binding its current files with 0 violations, "
        "and every spec under DIR/specs gets its declared verdict. Exit 1 with the list of "
        "what blocks.")
    p.add_argument("directory", nargs="?", type=Path, default=Path("."), metavar="DIR")
    p.add_argument("--json", action="store_true", help="one JSON object per line")
    p.add_argument("--rerun", type=_rerun_examples, default=None, metavar="N",
                   help="re-run a campaign of N examples per deployed model (default 50; "
                   "physical evidence: N MuJoCo trials, default 1), on a seed the gate derives "
                   "from the evidence's digest and the model's SHA-256 (not the evidence's "
                   "seed), with the evidence's recorded task and settings; a violation "
                   "blocks; N is 1 to 100000 (the gate always re-runs)")
    p.add_argument("--artifact", type=Path, action="append", default=None,
                   metavar="POLICY.tli.json",
                   help="an exported policy to be deployed (tli export; repeatable): it must "
                   "re-check (its hash, its text form), be the policy of a model the gate "
                   "passes, with the same spec, certificate and task, and be tested by the "
                   "current evidence (exported with it, or run by its trials in the C "
                   "evaluator), its numbers those its model exports to now; with physical "
                   "evidence it then drives the robot itself: N re-run trials (--rerun) with "
                   "the C evaluator in the loop, built with the system C compiler (needed)")
    p.set_defaults(handler=_gate)


def _task_file(spec: Path | None) -> Path | None:
    """The task file a spec names (an input the outputs must not overwrite), or None."""
    if spec is None:
        return None

    try:
        task = spec_task(load_spec(spec), spec)
    except TliError:
        return None
    return None if task is None or task.source.path is None else Path(task.source.path)


def _check_demos_fit_task(demos: list[Path], spec: Path | None) -> None:
    """Refuse demonstrations whose state dimension differs from the spec's task (before any
    learning: a model of another dimension would learn and certify, then every command that
    runs it would refuse it). The sensor columns are checked against the spec's inputs by the
    demonstration loader."""
    if spec is None:
        return

    task = spec_task(load_spec(spec), spec)
    if task is None:
        return
    for path in demos:
        demo = load_demo(path)
        n = int(demo.x.shape[1])
        if n != task.dim:
            raise DemoError(f"{path}: {n} state column(s) (x0..x{n - 1}), but the spec's task "
                            f"{task.name!r} ({task.where}) has {task.dim} states: these "
                            "demonstrations are not of this task")


def _learn(args: argparse.Namespace) -> int:

    task_file = _task_file(args.spec)
    check_plan(inputs=[*args.demos, args.spec, task_file], outputs=[(args.output, "model")])
    _check_demos_fit_task(args.demos, args.spec)
    control_dt = float(control_period(args.control_dt, args.spec))
    model = learn_model(args.demos, out_path=args.output, spec_path=args.spec, seed=args.seed,
                        eps=args.eps, rate=args.rate, control_dt=control_dt,
                        rate_budget=RATE_BUDGET if args.rate_budget is None else args.rate_budget,
                        clustering="em-bic" if args.baseline else "pc-gmm",
                        lyapunov="identity" if args.baseline else "p-qlf",
                        blocks=pose_blocks(args.spec) if args.blocks is None else args.blocks,
                        state_names=spec_state_names(args.spec))
    handoff = None
    if not args.no_handoff and args.spec is not None:

        ctx = context_for_spec(args.spec)
        if ctx is not None:
            handoff = learn_handoffs(ctx.task, ctx.automaton, model, dt=control_dt,
                                     goal_modes=ctx.goal_modes, samples=args.handoff_samples,
                                     seed=args.seed)
            model = handoff.model
    try:
        save_model(model, args.output)
    except ModelError as exc:  # learned numbers outside the declared limits: name the demos
        raise ModelError(f"the model learned from {', '.join(str(d) for d in args.demos)} is "
                         f"outside the declared numeric limits, not written: {exc} (rescale the "
                         "state or time units of the demonstrations)") from None
    for key, mm in model.modes.items():
        fit = mm.fit or {}
        record = {"model": str(args.output), "key": key, "mode": mm.mode,
                  "next_mode": mm.next_mode, "components": mm.ds.n_components,
                  "samples": fit.get("n_samples"), "attractor": mm.ds.attractor.tolist(),
                  "rate": fit.get("rate")}
        for name in ("rate_budget", "rate_within_budget"):
            if name in fit:
                record[name] = fit[name]
        if args.json:
            _emit(record)
        else:
            chosen = (f" (RMSE {fit['rate_rmse'] / fit['rate_reference_rmse'] - 1:+.1%} vs "
                      "rate 0)" if fit.get("rate_reference_rmse") else "")
            if fit.get("rate_within_budget") is False:
                chosen += (f" -- over the budget {fit['rate_budget']:g}: even the smallest "
                           "candidate rate costs more, kept")
            sys.stdout.write(f"{key}: K={mm.ds.n_components} components from "
                             f"{fit.get('n_samples')} samples, attractor "
                             f"{[round(v, 4) for v in mm.ds.attractor.tolist()]}, decay rate "
                             f"{fit.get('rate', 0.0):.3g}/s{chosen}\n")
    for claim in (handoff.claims if handoff is not None else ()):
        if args.json:
            _emit({"model": str(args.output), "handoff": claim.to_dict()})
        else:
            how = ("proved" if claim.established == "proved" else
                   f"sampled: {claim.samples} states, {claim.exits} exits, {claim.rests} rests")
            sys.stdout.write(f"hand-off {claim.key}: {claim.mode} -> "
                             f"{'|'.join(claim.hands_to) or '(goal)'}, {claim.cuts} cuts "
                             f"({claim.face_cuts} faces); {how}"
                             f"{'' if claim.holds else ' -- ' + claim.note}\n")
    if handoff is not None and not handoff.ok and not args.json:
        sys.stdout.write("warning: a hand-off does not hold on the drawn states (above): the "
                         "policy may leave these modes; see docs/explanation/handoff.md\n")
    if not args.json:
        sys.stdout.write(f"wrote {args.output} ({len(model.modes)} DS); certify it with: "
                         f"tli certify {args.output}\n")
    return 0


def default_certificate_path(model: Path) -> Path:
    """Where the project layout puts a model's certificate
    (:func:`tli_verify.tasks.project.model_files`): ``ROOT/certificates/<name>.cert.json`` for
    ``ROOT/models/<name>.model.json``; ``<name>.cert.json`` next to a model outside any
    ``models/`` folder."""
    return model_files(model).certificate


def _kind(path: Path, error: type[TliError]) -> str | None:
    """The ``kind`` field of a JSON file (None when it has none); unreadable: ``error``."""
    if path.is_dir():
        raise bad_input(error, f"{path}: is a directory, expected a JSON file")
    doc = read_json(path, what="JSON file", error=error)
    kind = doc.get("kind") if isinstance(doc, dict) else None
    return kind if isinstance(kind, str) else None


def _learn_orientation(args: argparse.Namespace) -> int:

    check_output_file(args.output, inputs=args.demos, what="orientation model")
    demos = [load_pose_demo(p) for p in args.demos]
    for d in demos:
        for note in d.notes:
            if args.json:
                _emit({"note": note})
            else:
                sys.stdout.write(f"note: {note}\n")
    ds, info = learn_quaternion_ds([d.t for d in demos], [d.q for d in demos], seed=args.seed,
                                   control_dt=float(control_period(args.control_dt, None)))
    write_orientation_model(ds, args.output, fit=info)
    record = {"model": str(args.output), "attractor": ds.attractor.tolist(),
              "components": info.n_components, "decay_rate": info.rate,
              "control_dt": info.control_dt, "seconds": round(info.seconds, 3)}
    if args.json:
        _emit(record)
    else:
        q = ", ".join(f"{v:.4f}" for v in ds.attractor)
        sys.stdout.write(f"wrote {args.output}: orientation DS, q* = ({q}) (w, x, y, z), "
                         f"K = {info.n_components}, decay rate {info.rate:.3g}/s, learned in "
                         f"{info.seconds:.2f} s; certify it with: tli certify {args.output} "
                         "-o CERT.json\n")
    return 0


def _certify_orientation(args: argparse.Namespace) -> int:
    from tli_verify.certification.orientation import (
        issue_orientation_certificate,
        write_orientation_certificate,
    )

    if args.repair is not None:
        raise bad_input(ModelError, f"{args.model}: --repair is not available for orientation "
                        "models")
    out: Path = args.output or default_certificate_path(args.model)
    check_output_file(out, inputs=[args.model], what="certificate")
    dt = control_period(args.dt, None)
    doc = issue_orientation_certificate(args.model, out, dt=dt)
    write_orientation_certificate(doc, out)
    ex = doc["exact"]
    record = {"certificate": str(out), "model": str(args.model), "kind": "orientation",
              "dt": doc["dt"], "decay_rate": ex["decay_rate"],
              "region_V_below": ex["region_V_below"], "exact": True}
    if args.json:
        _emit(record)
    else:
        angle = float(Fraction(ex["region_angle_squared_below"])) ** 0.5
        sys.stdout.write(f"orientation: P > 0, {len(ex['continuous'])} components with "
                         f"A_k^T P + P A_k < 0, decrease per step at dt = {doc['dt']}, decay "
                         f"rate {float(Fraction(ex['decay_rate'])):.4g}/s, chart region "
                         f"V < {float(Fraction(ex['region_V_below'])):.4g} (every start within "
                         f"{angle * 57.29577951308232:.1f} degrees of q*); exact: yes\n"
                         f"wrote {out}\n")
    return 0


def _check_orientation_cert(args: argparse.Namespace) -> int:
    from tli_verify.certification.orientation import check_orientation_certificate

    if args.model is not None:
        raise bad_input(CertificateError, f"{args.certificate}: --model is not available for "
                        "orientation certificates (they bind their model file)")
    check = check_orientation_certificate(args.certificate)
    for item in check.failures:
        if args.json:
            _emit({"certificate": str(args.certificate), "ok": False, "message": item})
        else:
            sys.stdout.write(f"FAIL  {item}\n")
    if args.json:
        _emit({"certificate": str(args.certificate), "kind": "orientation", "valid": check.ok})
    if not check.ok:
        raise CertificateError(f"{args.certificate}: orientation certificate does not re-check "
                               f"({len(check.failures)} problem(s)): {check.failures[0]}")
    if not args.json:
        sys.stdout.write(f"{args.certificate}: valid (orientation DS re-checked exactly)\n")
    return 0


def _certify(args: argparse.Namespace) -> int:
    from tli_verify.certification.certificate import issue_certificate, write_certificate

    if _kind(args.model, ModelError) == ORIENTATION_MODEL_KIND:
        return _certify_orientation(args)
    model_path: Path = args.model
    spec_path = load_model(args.model).spec_path
    dt = control_period(args.dt, spec_path)
    task_file = _task_file(spec_path)
    inputs = [args.model, *([spec_path] if spec_path else []), *([task_file] if task_file else [])]
    out: Path = args.output or default_certificate_path(args.repair or args.model)
    if args.repair is not None:
        check_output_file(args.repair, inputs=inputs, what="repaired model")
        inputs.append(args.repair)
    check_output_file(out, inputs=inputs, what="certificate")
    if args.repair is not None:
        from tli_verify.certification.repair import repair_model

        result = repair_model(args.model, args.repair, dt=dt)
        save_model(result.model, args.repair)
        model_path = args.repair
        line = {"repaired_model": str(args.repair), "repaired": list(result.repaired),
                "kept": list(result.kept)}
        if args.json:
            _emit(line)
        else:
            sys.stdout.write(f"wrote {args.repair}: new P for "
                             f"{', '.join(result.repaired) or 'no DS'}; own P kept for "
                             f"{', '.join(result.kept) or 'no DS'}\n")
    doc = issue_certificate(model_path, cert_path=out, dt=dt)
    write_certificate(doc, out)
    for key, entry in doc["modes"].items():
        record = {"certificate": str(out), "model": str(model_path), "key": key,
                  "lambda_min_P": entry["lambda_min_P"], "dt": doc["control_period"]["dt"],
                  "decay_rate": entry["decay_rate"],
                  "max_lambda_max": max(entry["lambda_max"]), "exact": True}
        if args.json:
            _emit(record)
        else:
            sys.stdout.write(f"{key}: P > 0 (lambda_min {entry['lambda_min_P']:.4g}), "
                             f"{len(entry['lambda_max'])} components with A_k^T P + P A_k < 0 "
                             f"(max lambda_max {max(entry['lambda_max']):.4g}), decrease per "
                             f"step at dt = {doc['control_period']['dt']}, decay rate "
                             f"{entry['decay_rate_float']:.4g}/s; exact: yes\n")
    if not args.json:
        sys.stdout.write(f"wrote {out}\n")
    return 0


def _check_cert(args: argparse.Namespace) -> int:
    from tli_verify.certification.certificate import check_certificate
    from tli_verify.certification.orientation import ORIENTATION_CERT_KIND

    for path, what, error in ((args.certificate, "certificate", CertificateError),
                              (args.model, "model", ModelError)):
        if path is not None and path.is_dir():  # not "no such file": say what it is
            raise bad_input(error, f"{path}: is a directory, expected a {what} file")
    if args.certificate.is_file() and \
            _kind(args.certificate, CertificateError) == ORIENTATION_CERT_KIND:
        return _check_orientation_cert(args)
    check = check_certificate(args.certificate, model_path=args.model)
    if args.json:
        for item in check.passed:
            _emit({"certificate": check.path, "ok": True, "message": item})
        for item in check.problems:
            _emit({"certificate": check.path, "ok": False, "message": item})
        _emit({"certificate": check.path, "model": check.model_path, "valid": check.ok})
    else:
        for item in check.passed:
            sys.stdout.write(f"ok    {item}\n")
        for item in check.problems:
            sys.stdout.write(f"FAIL  {item}\n")
    handoff_ok = True
    if check.ok and check.model_path:

        model = load_model(check.model_path)
        if model.spec_path is not None and model.spec_path.is_file():
            handoff_ok, lines = handoff_status(model, model.spec_path)
            for line in lines:
                if args.json:
                    _emit({"certificate": check.path, "ok": handoff_ok, "message": line})
                else:
                    sys.stdout.write(f"{'ok   ' if handoff_ok else 'FAIL '} {line}\n")
    if not check.ok:
        raise CertificateError(f"{check.path}: certificate does not re-check "
                               f"({len(check.problems)} problem(s)): {check.problems[0]}")
    if not handoff_ok:
        raise CertificateError(f"{check.path}: the model's hand-off record does not re-check "
                               "(above)")
    if not args.json:
        sys.stdout.write(f"{check.path}: valid (re-checked exactly against {check.model_path})\n")
    return 0


def _gate(args: argparse.Namespace) -> int:
    from tli_verify.deploy.gate import run_gate

    report = run_gate(args.directory, rerun=args.rerun, artifacts=args.artifact or ())
    for item in report.items:
        if args.json:
            _emit(item.to_dict())
        else:
            sys.stdout.write(f"{'ok   ' if item.ok else 'BLOCK'} {item.kind:<11} {item.path}: "
                             f"{item.check}: {item.message}\n")
    summary = (f"{report.count('certificate')} certificate(s), {report.count('model')} "
               f"model(s), {report.count('spec')} spec(s)")
    if args.json:
        _emit({"gate": "pass" if report.ok else "blocked", "root": report.root,
               "blockers": len(report.blockers)})
    if not report.ok:
        raise GateError(f"gate blocked: {len(report.blockers)} problem(s) in {summary}; first: "
                        f"{report.blockers[0].path}: {report.blockers[0].message}")
    if not args.json:
        sys.stdout.write(f"gate: pass ({summary})\n")
    return 0


def demo_stage(out: Path) -> list[str]:
    """``tli demo``: learn the scooping model from the bundled demos, certify and re-check it.

    Writes ``out/motion/scoop.model.json``, ``out/motion/scoop.cert.json`` and a plot
    ``out/motion/scoop_modes.png``; returns one summary line per result.
    """
    from tli_verify.certification.certificate import (
        check_certificate,
        issue_certificate,
        write_certificate,
    )

    demos = sorted(bundled_dir("demos").glob("scoop_*.csv"))
    spec = bundled_dir("specs") / "scoop.toml"
    if not demos:
        return ["motion: no bundled demos/scoop_*.csv found; skipped"]
    target = out / "motion"
    model_path = target / "scoop.model.json"
    cert_path = target / "scoop.cert.json"
    model = learn_model(demos, out_path=model_path, spec_path=spec if spec.is_file() else None,
                        seed=0)
    save_model(model, model_path)
    write_certificate(issue_certificate(model_path, cert_path=cert_path), cert_path)
    check = check_certificate(cert_path)
    sizes = ", ".join(f"{k}: K={m.ds.n_components}" for k, m in model.modes.items())
    lines = [f"motion: learned {len(model.modes)} mode DS from {len(demos)} demos -> "
             f"{model_path} ({sizes})",
             f"motion: certificate {cert_path}: "
             f"{'re-checks exactly' if check.ok else 'INVALID: ' + check.problems[0]}"]
    if model.dim == 2:
        _plot_model(model, demos, target / "scoop_modes.png")
        lines.append(f"motion: streamlines of every mode -> {target / 'scoop_modes.png'}")
    return lines


def _plot_model(model: Any, demo_paths: list[Path], path: Path) -> None:
    """Streamlines of each mode's (modulated) DS with the demonstrations (2D models)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    demos = [load_demo(p) for p in demo_paths]
    pts = np.concatenate([d.x for d in demos])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    pad = 0.25 * (hi - lo).max()
    gx, gy = np.meshgrid(np.linspace(lo[0] - pad, hi[0] + pad, 60),
                         np.linspace(lo[1] - pad, hi[1] + pad, 60))
    grid = np.column_stack([gx.ravel(), gy.ravel()])
    keys = list(model.modes)
    fig, axes = plt.subplots(1, len(keys), figsize=(3.6 * len(keys), 3.6), squeeze=False)
    for ax, key in zip(axes[0], keys, strict=True):
        V = model.modes[key].velocity(grid)
        ax.streamplot(gx, gy, V[:, 0].reshape(gx.shape), V[:, 1].reshape(gx.shape),
                      color="0.6", density=1.0, linewidth=0.6)
        for d in demos:
            ax.plot(d.x[:, 0], d.x[:, 1], color="k", linewidth=0.8)
        star = model.modes[key].ds.attractor
        ax.plot(star[0], star[1], marker="*", color="tab:orange", markersize=12)
        ax.set_title(f"mode {key}", fontsize=9)
        ax.set_aspect("equal")
    fig.tight_layout()
    save_figure(fig, path, dpi=90)
