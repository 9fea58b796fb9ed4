"""``tli export``: the policy artifact, its schema and hash binding, and the gate's refusal."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from tests.support.cli import run
from tli_verify.deploy.export import (
    check_artifact,
    export_policy,
    render_text,
    text_path_for,
)
from tli_verify.errors import ExportError, GateError
from tli_verify.io import sha256_file


def test_export_writes_a_self_describing_artifact_bound_to_its_sources(project: Path,
                                                                       tmp_path: Path) -> None:
    out = tmp_path / "out" / "scoop.tli.json"
    out.parent.mkdir()
    ex = export_policy(project / "models" / "scoop.model.json", out, rerun=0)
    art = check_artifact(out)  # schema + its own hash
    assert art == json.loads(out.read_text())
    assert art["format"] == "tli-policy" and art["schema_version"] == 2
    assert ex.c_loaded == (shutil.which("cc") is not None or shutil.which("gcc") is not None)
    # an artifact of the earlier schema (no stall rule) is named as such, not as a bad file
    old = dict(art, schema_version=1)
    old.pop("stall")
    v1 = tmp_path / "v1.tli.json"
    v1.write_text(json.dumps(old))
    with pytest.raises(ExportError, match="schema version 1; this tli-verify reads version 2"):
        check_artifact(v1)
    assert art["content_sha256"] == ex.content_sha256
    # the text form: the same content, the same hash on its closing line
    text = text_path_for(out).read_text()
    body, last = text[: text.rindex("sha256 ")], text.splitlines()[-1]
    assert last == f"sha256 {ex.content_sha256}"
    assert body == render_text({k: v for k, v in art.items() if k != "content_sha256"})
    # provenance: the SHA-256 of the files it was made from
    for what, sub, name in (("model", "models", "scoop.model.json"),
                            ("certificate", "certificates", "scoop.cert.json"),
                            ("spec", "specs", "scoop.toml"),
                            ("evidence", "certificates", "scoop.campaign.json")):
        assert art["sources"][what]["sha256"] == sha256_file(project / sub / name)
    aut = art["automaton"]
    assert aut["inputs"] == ["r", "s", "t"] and aut["goal_modes"] == ["d"]
    keys = {d["key"] for d in art["ds"]}
    assert all(s["ds"] in keys for s in aut["states"])
    assert art["dt"] == 0.01
    ds = art["ds"][0]
    k, n = len(ds["priors"]), art["dim"]
    assert len(ds["gmm"]["quadratic"]) == k and len(ds["gmm"]["quadratic"][0]) == n * (n + 1) // 2
    # b_k = -A_k x*
    a0, xs = ds["A"][0], ds["attractor"]
    assert ds["b"][0] == pytest.approx([-sum(a0[i][j] * xs[j] for j in range(n))
                                        for i in range(n)], rel=1e-12, abs=1e-15)


def test_an_edited_artifact_is_refused(project: Path, tmp_path: Path) -> None:
    out = tmp_path / "p.tli.json"
    export_policy(project / "models" / "scoop.model.json", out, rerun=0)
    art = json.loads(out.read_text())
    art["ds"][0]["A"][0][0][0] *= 1.0000001
    out.write_text(json.dumps(art))
    with pytest.raises(ExportError, match=r"content_sha256 .* is not the hash of its content"):
        check_artifact(out)


def test_a_model_the_gate_blocks_is_not_exported(project: Path, tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    model = project / "models" / "scoop.model.json"
    doc = json.loads(model.read_text())
    first = next(iter(doc["modes"].values()))
    first["attractor"][0] += 1e-3  # the certificate no longer covers these bytes
    model.write_text(json.dumps(doc))
    out = tmp_path / "p.tli.json"
    with pytest.raises(GateError, match="refused: the gate blocks"):
        export_policy(model, out, rerun=0)
    assert not out.exists() and not text_path_for(out).exists()
    code, stdout, err = run(capsys, "export", str(project), "-o", str(out), "--rerun", "1")
    assert code == 1 and stdout == ""
    assert err.count("\n") == 1 and err.startswith("error: ") and "gate blocks" in err
    assert not out.exists()


def test_cli_refuses_bad_input_in_one_line(project: Path, tmp_path: Path,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run(capsys, "export", str(tmp_path / "nowhere"), "-o",
                       str(tmp_path / "p.json"))
    assert code == 2 and err.count("\n") == 1 and "no such project" in err
    code, _, err = run(capsys, "export", str(project), "--model", "nope", "-o",
                       str(tmp_path / "p.json"))
    assert code == 2 and err.count("\n") == 1 and "no model 'nope'" in err
    model = project / "models" / "scoop.model.json"
    code, _, err = run(capsys, "export", str(model), "-o", str(model))  # read/write overlap
    assert code == 2 and err.count("\n") == 1
    code, _, err = run(capsys, "export", str(model), "-o", str(tmp_path / "p.json"),
                       "--max-online-cuts", "64")
    assert code == 2 and err.count("\n") == 1 and "max-online-cuts" in err


def test_cli_exports_a_gated_project(project: Path, tmp_path: Path,
                                     capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "scoop.tli.json"
    code, stdout, err = run(capsys, "export", str(project), "-o", str(out), "--rerun", "2")
    assert code == 0, err
    art = check_artifact(out)
    assert art["content_sha256"] in stdout and text_path_for(out).is_file()


def test_the_gate_binds_a_deployed_artifact_to_what_it_checked(project: Path,
                                                               tmp_path: Path) -> None:
    """``tli gate --artifact``: the exported policy passes; each forgery only the binding
    catches blocks it -- a text form edited behind a valid JSON, an artifact of another
    model, a certificate re-issued since, evidence replaced since (no campaign tested it)."""
    from tli_verify.deploy.gate import run_gate

    out = tmp_path / "scoop.tli.json"
    export_policy(project / "models" / "scoop.model.json", out, rerun=0)

    def artifact_line(path: Path) -> tuple[bool, str]:
        report = run_gate(project, rerun=0, artifacts=[path])
        item = next(i for i in report.items if i.kind == "artifact")
        return item.ok, item.message

    ok, why = artifact_line(out)
    assert ok, why
    # the text form the C evaluator loads, edited (the JSON and its own hash untouched)
    text = text_path_for(out)
    good = text.read_text()
    text.write_text(good.replace("dt 0.01", "dt 0.02", 1))
    ok, why = artifact_line(out)
    assert not ok and "text form" in why and "edited" in why
    text.write_text(good)
    # evidence replaced since the export, and its trials never ran the artifact
    evidence = project / "certificates" / "scoop.campaign.json"
    saved = evidence.read_bytes()
    evidence.write_bytes(saved.replace(b"\n", b"\n ", 1))
    ok, why = artifact_line(out)
    assert not ok and "no campaign tested it" in why
    evidence.write_bytes(saved)
    assert artifact_line(out)[0]
    # an artifact whose recorded model is none of the project's (digest recomputed)
    from tli_verify.deploy.export import write_artifact

    art = json.loads(out.read_text())
    art["sources"]["model"]["sha256"] = "0" * 64
    other = tmp_path / "other.tli.json"
    write_artifact(art, other)
    ok, why = artifact_line(other)
    assert not ok and "none of the project's models" in why
    # a certificate re-issued since the export (same model, other bytes): binding broken
    cert = project / "certificates" / "scoop.cert.json"
    doc = json.loads(cert.read_text())
    art = json.loads(out.read_text())
    art["sources"]["certificate"]["sha256"] = "1" * 64
    forged = tmp_path / "forged.tli.json"
    write_artifact(art, forged)
    ok, why = artifact_line(forged)
    assert not ok and "its certificate" in why
    assert doc  # the real certificate untouched
    # the content edited and re-hashed, its sources left alone (hash, text form, bindings
    # and campaign all check): a gain of the DS, then an edge of the automaton
    art = json.loads(out.read_text())
    art["ds"][1]["A"][0][0][0] *= 1.5
    write_artifact(art, forged)
    ok, why = artifact_line(forged)
    assert not ok and "its content (ds[1].A[0][0][0])" in why and "re-export" in why
    # ... while the last bits of a re-derived number may differ (another CPU's BLAS kernel
    # sums the GMM's quadratic form in another order): within 1e-9 relative it passes
    art = json.loads(out.read_text())
    art["ds"][1]["gmm"]["constant"][0] *= 1 + 1e-13
    art["ds"][0]["P"][0][0] *= 1 - 1e-12
    write_artifact(art, forged)
    ok, why = artifact_line(forged)
    assert ok, why
    art["ds"][1]["gmm"]["constant"][0] *= 1 + 1e-7
    write_artifact(art, forged)
    ok, why = artifact_line(forged)
    assert not ok and "ds[1].gmm.constant[0]" in why
    art = json.loads(out.read_text())
    art["automaton"]["edges"][0]["to"] = art["automaton"]["edges"][1]["to"]
    write_artifact(art, forged)
    ok, why = artifact_line(forged)
    assert not ok and "its content (automaton" in why
    art = json.loads(out.read_text())  # an older exporter's name is no forgery
    art["tool"]["version"] = "0.0.1"
    write_artifact(art, forged)
    assert artifact_line(forged)[0]
