"""Fingerprint ``tli spec import`` over a folder of Spectra / slugs files (issue 33).

Writes, per file, the outcome (``ok`` / ``err``) and the SHA-256 of the TOML (or of the error
line) to a JSON file, so two versions of the importer can be compared byte for byte::

    python scripts/import_fingerprint.py SUITE_DIR before.json     # on the old code
    python scripts/import_fingerprint.py SUITE_DIR after.json      # on the new code
    cmp before.json after.json

The foreign/ package split was checked this way on the 662 files of the public Spectra suite
(SpectraSynthesizer/spectra-specs): 662 identical (565 imports, 97 refusals).
"""

from __future__ import annotations

import hashlib
import json
import sys
from pathlib import Path

from tli_verify.errors import SpecError
from tli_verify.logic.foreign import FORMATS, import_spec_file


def main(argv: list[str]) -> int:
    if len(argv) != 2:
        sys.stderr.write("usage: python scripts/import_fingerprint.py SUITE_DIR OUT.json\n")
        return 2
    root, out = Path(argv[0]), Path(argv[1])
    files = sorted(p for p in root.rglob("*") if p.suffix in FORMATS and p.is_file())
    result: dict[str, list[str]] = {}
    for f in files:
        try:
            kind, text = "ok", import_spec_file(f)
        except SpecError as exc:
            kind, text = "err", str(exc)
        result[str(f.relative_to(root))] = [kind, hashlib.sha256(text.encode()).hexdigest()]
    out.write_text(json.dumps(result, indent=1, sort_keys=True) + "\n", encoding="utf-8")
    sys.stdout.write(f"{len(files)} files: {sum(v[0] == 'ok' for v in result.values())} "
                     f"imported, {sum(v[0] == 'err' for v in result.values())} refused\n")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
