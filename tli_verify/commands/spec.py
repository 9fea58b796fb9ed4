"""``tli spec check``, ``tli spec automaton``, ``tli spec import`` and ``tli spec infer``: GR(1)
realizability, task automata, specs translated from Spectra and slugs, and specs inferred from
demonstrations."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from tli_verify.commands import exit_code, output_path
from tli_verify.errors import OutputError, TliError
from tli_verify.io import atomic_write_text, bundled_dir, canonical_json
from tli_verify.logic.check import check_spec, check_spec_file, synthesize
from tli_verify.logic.foreign import import_spec_file
from tli_verify.logic.infer import infer_spec_text, load_labels
from tli_verify.logic.spec import load_spec, parse_spec


def register(sub: argparse._SubParsersAction[Any]) -> None:
    """Register ``tli spec ...``."""
    spec = sub.add_parser("spec", help="check GR(1) task specs and build their task automata")
    ssub = spec.add_subparsers(dest="spec_command", metavar="SUBCOMMAND",
                               parser_class=type(spec))
    spec.set_defaults(handler=lambda _a: _usage(spec))

    check = ssub.add_parser(
        "check", help="decide realizability of each spec; diagnose unrealizable ones",
        description="One verdict per file, with a well-separation check. Exit 0 if all are "
        "realizable (and, with --strict, well-separated), 1 if any is not, 2 on any bad input.")
    check.add_argument("files", nargs="+", type=Path, metavar="FILE")
    check.add_argument("--json", action="store_true", help="one JSON object per line")
    check.add_argument("--explain", action="store_true",
                       help="also print the GR(1) game, including constraints added from [modes]")
    check.add_argument("--strict", action="store_true",
                       help="exit 1 also for realizable specs that are not well-separated")
    check.add_argument("--core", action="store_true",
                       help="report a minimal unrealizable core of guarantees, with file lines")
    check.add_argument("--hints", action="store_true",
                       help="report formulas that do not affect the verdict (vacuity hints)")
    check.set_defaults(handler=_check)

    aut = ssub.add_parser(
        "automaton", help="synthesize the task automaton (Mealy machine) of a realizable spec",
        description="Writes JSON (states, initial, transitions, mode_transitions) or Graphviz "
        "DOT, by the extension of -o. Exit 1 if the spec is unrealizable.")
    aut.add_argument("file", type=Path, metavar="FILE")
    aut.add_argument("-o", "--output", type=output_path, default=None,
                     help="OUT.json or OUT.dot (default: a summary on stdout)")
    aut.add_argument("--json", action="store_true", help="print the automaton JSON on stdout")
    aut.set_defaults(handler=_automaton)

    imp = ssub.add_parser(
        "import", help="translate a Spectra or slugs spec to a TOML spec",
        description="Reads FILE.spectra, FILE.structuredslugs or FILE.slugsin and writes our "
        "TOML spec (integers and enumerations bit-blasted, with their domain constraints). "
        "Every construct GR(1) TOML cannot express is refused by name and line (exit 2). "
        "The spec gets semantics = \"textbook\" (the reading of Spectra and slugs) unless "
        "--semantics tli. Without -o the TOML goes to stdout.")
    imp.add_argument("file", type=Path, metavar="FILE")
    imp.add_argument("-o", "--output", type=output_path, default=None, metavar="OUT.toml")
    imp.add_argument("--semantics", choices=("textbook", "tli"), default="textbook",
                     help="the reading of safety at time 0 the spec asks for (default: "
                     "textbook, the source tool's)")
    imp.set_defaults(handler=_import)

    infer = ssub.add_parser(
        "infer", help="infer the partial GR(1) spec that demonstrations imply (appendix F)",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Writes the spec the demonstrations imply (paper appendix F, 'Automatic "
        "construction of GR(1) LTL formulas'): initial conditions, the goal (the modes the "
        "demonstrations end in), the demonstrated mode changes as phi_t^s, the demonstrated "
        "sensor changes and fairness toward the goal as the environment part, and the "
        "perturbation marker p with the goal GF(goal | p) (details: tli_verify.logic.infer). "
        "The spec is checked; exit 0 if realizable and well-separated, 1 if not (the file is "
        "written either way), 2 on bad input.",
        epilog="example (scoop, paper Fig. 3(a)):\n"
        "  tli spec infer demos/scoop_*.csv --modes specs/scoop.toml -o scoop-inferred.toml\n"
        "gives the black edges a->b->c->d. Online, perturbations add b->a, c->a, c->b\n"
        "(tli_verify.logic.infer.add_transition, re-synthesized each time), and the automaton\n"
        "grows to the one of specs/scoop.toml, Fig. 3(a) (scripts/infer_scoop.py shows it).")
    infer.add_argument("demos", nargs="+", type=Path, metavar="DEMO.csv")
    infer.add_argument("--modes", type=Path, required=True, metavar="LABELS",
                       help="TOML file with a [modes] table (mode = \"sensor formula\"), "
                       "or a spec file")
    infer.add_argument("-o", "--output", type=output_path, required=True, metavar="SPEC.toml")
    infer.add_argument("--name", default=None, help="spec name (default: the output's stem)")
    infer.set_defaults(handler=_infer)


def _usage(parser: argparse.ArgumentParser) -> int:
    parser.print_help(sys.stderr)
    return 2


def _explain(check: Any) -> list[str]:
    spec = check.spec
    lines = [f"  inputs (environment): {', '.join(spec.inputs)}",
             f"  outputs (system): {', '.join(spec.outputs)}"]
    if spec.modes is not None:
        lines.append("  modes: " + ", ".join(f"{m} = {lab}" for m, lab in spec.modes.items()))
    for side in (spec.assume, spec.guarantee):
        for f in side.all():
            tag = "  [added from [modes]]" if f.origin == "modes" else ""
            lines.append(f"  {f.label}: {f.text}{tag}")
    added = spec.added()
    if added:
        lines.append(f"  {len(added)} constraint(s) added from [modes]: one mode at a time, a "
                     "mode only where its label holds, sensors always show a mode label "
                     "(paper Asm. 3)")
    return lines


def _task_fit_warnings(spec: Any, path: Path) -> list[str]:
    """The spec's task against its assumptions (:mod:`tli_verify.tasks.fit`): a sensor change
    the task can produce under a push that the spec rules out, at most 3 named, and the count;
    nothing for a spec that names no task or a task whose sensors a plug-in computes."""
    from tli_verify.tasks.fit import task_spec_mismatches
    from tli_verify.tasks.project import spec_task

    try:
        task = spec_task(spec, path)
        if task is None or not bool(getattr(task.sensor_model, "cell_based", False)) or \
                set(task.sensor_names) != set(spec.inputs):
            return []
        found = task_spec_mismatches(task, synthesize(spec))
    except TliError:
        return []
    out = [f"task {task.name!r}: {m.describe()}" for m in found[:3]]
    if len(found) > 3:
        out.append(f"task {task.name!r}: {len(found) - 3} more such change(s) (tli task check "
                   f"{task.source.path or task.name} --spec {path})")
    return out


def _check(args: argparse.Namespace) -> int:

    worst = 0
    for path in args.files:
        try:
            result = check_spec_file(path, core=args.core, hints=args.hints)
        except TliError as exc:
            sys.stderr.write(f"error: {exc}\n")
            worst = max(worst, exit_code(exc))
            continue
        if not result.realizable or (args.strict and not result.well_separated):
            worst = max(worst, 1)
        if args.json:
            record = result.to_dict()
            if args.explain:
                record["explain"] = [line.strip() for line in _explain(result)]
            sys.stdout.write(json.dumps(record, sort_keys=True) + "\n")
            continue
        verdict = "realizable" if result.realizable else "UNREALIZABLE"
        reading = ", textbook semantics" if result.spec.semantics == "textbook" else ""
        sys.stdout.write(f"{path}: {verdict} ({result.seconds * 1000:.1f} ms{reading})\n")
        for w in result.warnings:
            sys.stdout.write(f"  warning: {w}\n")
        if result.realizable:
            for w in _task_fit_warnings(result.spec, path):
                sys.stdout.write(f"  warning: {w}\n")
        if result.diagnosis is not None:
            for line in result.diagnosis.lines():
                sys.stdout.write(f"  {line}\n")
        if not result.well_separated:
            for line in result.well_separation.lines():
                sys.stdout.write(f"  {line}\n")
        if result.core is not None:
            sys.stdout.write(f"  unrealizable core ({len(result.core.formulas)} of "
                             f"{len(result.spec.guarantee.all())} guarantees; removing any one "
                             "makes the rest realizable):\n")
            for line in result.core.lines():
                sys.stdout.write(f"  {line}\n")
        for hint in result.hints:
            sys.stdout.write(f"  hint: {hint}\n")
        if args.explain:
            sys.stdout.write("\n".join(_explain(result)) + "\n")
    return worst


def write_automaton(automaton: Any, out: Path) -> None:
    """Write ``automaton`` as JSON or DOT (by ``out``'s extension), atomically."""
    if out.suffix == ".dot":
        atomic_write_text(out, automaton.to_dot())
    elif out.suffix == ".json":
        atomic_write_text(out, canonical_json(automaton.to_dict()))
    else:
        raise TliError(f"{out}: output must end in .json or .dot")


def _automaton(args: argparse.Namespace) -> int:

    automaton = synthesize(load_spec(args.file))
    if args.output is not None:
        write_automaton(automaton, args.output)
    if args.json:
        sys.stdout.write(canonical_json(automaton.to_dict()))
    elif args.output is None:
        sys.stdout.write(f"{args.file}: {len(automaton.states)} states, "
                         f"{len(automaton.transitions)} transitions\n")
        for s in automaton.states:
            sensors = ",".join(s.inputs) or "-"
            outs = [f"[{t.label(automaton.inputs)}]->{t.target}"
                    for t in automaton.transitions if t.source == s.id]
            init = "*" if s.id in automaton.initial else " "
            sys.stdout.write(f" {init}{s.id:3d}  mode {s.mode:8s} sensors [{sensors}]  "
                             f"{' '.join(outs)}\n")
        pairs = " ".join(f"{a}->{b}" for a, b in automaton.mode_transitions())
        sys.stdout.write(f"mode transitions: {pairs}\n")
    else:
        sys.stdout.write(f"wrote {args.output}\n")
    return 0


def _import(args: argparse.Namespace) -> int:

    if args.output is not None and args.output.suffix != ".toml":
        raise OutputError(f"{args.output}: output must end in .toml")
    text = import_spec_file(args.file,
                            semantics=None if args.semantics == "tli" else args.semantics)
    # the result must load; a problem in it is the input's (nothing is written yet)
    spec = parse_spec(text, path=f"{args.file} (translated)", default_name=args.file.stem)
    if args.output is None:
        sys.stdout.write(text)
        return 0
    atomic_write_text(args.output, text)
    sys.stdout.write(f"wrote {args.output}: {len(spec.inputs)} inputs, {len(spec.outputs)} "
                     f"outputs, {len(spec.formulas())} formulas\n")
    return 0


def _infer(args: argparse.Namespace) -> int:
    from tli_verify.demos import load_demos

    demos = load_demos(args.demos)
    labels = load_labels(args.modes, demos[0].sensor_names)
    name = args.name or args.output.stem
    text = infer_spec_text(demos, labels, name=name,
                           sources=[p.name for p in args.demos])
    spec = parse_spec(text, path=str(args.output), default_name=name)
    atomic_write_text(args.output, text)
    result = check_spec(spec)
    ok = result.realizable and result.well_separated
    verdict = "realizable" if result.realizable else "UNREALIZABLE"
    separated = "well-separated" if result.well_separated else "NOT well-separated"
    sys.stdout.write(f"wrote {args.output}: {verdict}, {separated}\n")
    if ok:
        automaton = synthesize(spec)
        pairs = " ".join(f"{a}->{b}" for a, b in automaton.mode_transitions() if a != b)
        sys.stdout.write(f"  automaton: {len(automaton.states)} states; mode changes {pairs}\n")
    for w in result.warnings:
        sys.stdout.write(f"  warning: {w}\n")
    return 0 if ok else 1


def demo_stage(out: Path) -> list[str]:
    """Check every spec in ``specs/``; write each automaton as JSON and DOT under ``out``."""
    specs = sorted(bundled_dir("specs").glob("*.toml"))
    lines = [f"[spec] checking {len(specs)} specs in specs/"]
    adir = out / "automata"
    for path in specs:
        result = check_spec_file(path)
        verdict = "realizable" if result.realizable else "unrealizable"
        expected = "as expected" if result.as_expected else "NOT AS EXPECTED"
        separated = "well-separated" if result.well_separated else "NOT well-separated"
        lines.append(f"[spec] {path}: {verdict}, {separated} ({expected}, "
                     f"{result.seconds * 1000:.1f} ms)")
        if result.realizable:
            automaton = synthesize(result.spec)
            write_automaton(automaton, adir / f"{path.stem}.json")
            write_automaton(automaton, adir / f"{path.stem}.dot")
            from tli_verify.plotting import draw_mode_graph

            draw_mode_graph(automaton, adir / f"{path.stem}.png")
            pairs = " ".join(f"{a}->{b}" for a, b in automaton.mode_transitions() if a != b)
            lines.append(f"[spec]   automaton: {len(automaton.states)} states; mode changes "
                         f"{pairs}; wrote {adir / path.stem}.json/.dot/.png")
        elif result.diagnosis is not None:
            lines.append(f"[spec]   why: {result.diagnosis.kind}: {result.diagnosis.summary}")
    return lines
