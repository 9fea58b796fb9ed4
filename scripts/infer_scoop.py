"""Paper appendix F, "Automatic construction of GR(1) LTL formulas", on the scoop task.

Infers the demonstration-only spec from ``demos/scoop_*.csv`` with the labels of
``specs/scoop.toml`` (:func:`tli_verify.logic.infer.infer_spec`): its automaton has the black
edges of paper Fig. 3(a) only (``a -> b -> c -> d``). Then adds, one at a time, the transitions
perturbations discover online (``b -> a``, ``c -> a``, ``c -> b``; the grey edges) with
:func:`tli_verify.logic.infer.add_transition`, re-synthesizing after each, and compares the
final automaton with the one of ``specs/scoop.toml`` (Fig. 3(a)).

Usage: ``.venv/bin/python scripts/infer_scoop.py [-o GROWN.toml]``. Uses only the sensor
columns of the demonstrations, not their geometry. Exit 0 when the grown automaton is
Fig. 3(a)'s, 1 otherwise.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from tli_verify.demos import load_demos
from tli_verify.io import atomic_write_text, bundled_dir
from tli_verify.logic.check import check_spec, synthesize
from tli_verify.logic.infer import add_transition, infer_spec, load_labels, spec_to_toml
from tli_verify.logic.spec import load_spec

PERTURBATIONS = (("b", "a"), ("c", "a"), ("c", "b"))


def _changes(spec: object) -> str:
    pairs = synthesize(spec).mode_transitions()  # type: ignore[arg-type]
    return " ".join(f"{a}->{b}" for a, b in pairs if a != b)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-o", "--output", type=Path, default=None,
                        help="write the grown spec here")
    args = parser.parse_args()
    demos = load_demos(sorted(bundled_dir("demos").glob("scoop_*.csv")))
    paper_path = bundled_dir("specs") / "scoop.toml"
    spec = infer_spec(demos, load_labels(paper_path, demos[0].sensor_names),
                      name="scoop-inferred")
    result = check_spec(spec)
    print(f"inferred from {len(demos)} demonstrations: realizable={result.realizable} "
          f"well-separated={result.well_separated}; mode changes {_changes(spec)}")
    for a, b in PERTURBATIONS:
        spec = add_transition(spec, a, b)
        print(f"+ {a}->{b} (perturbation): mode changes {_changes(spec)}")
    paper = synthesize(load_spec(paper_path)).to_dict()
    ours = synthesize(spec).to_dict()
    same = ({k: v for k, v in ours.items() if k != "name"}
            == {k: v for k, v in paper.items() if k != "name"})
    print(f"grown automaton == specs/scoop.toml automaton (Fig. 3(a)): {same}")
    if args.output is not None:
        atomic_write_text(args.output, spec_to_toml(spec))
        print(f"wrote {args.output}")
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
