"""A campaign from a user's own Python script gets what ``tli verify --evidence`` gets (issue 32,
part 2), run as the user runs it: ``python script.py`` in a project folder.

* evidence written with ``tli.write_campaign_evidence(config, result)`` from a
  ``CampaignConfig`` with its defaults records the window and pushes the campaign used (the
  task's), so the gate's evidence check passes it; its return value is ``(path, record)``;
* a script that calls ``run_campaign`` at its top level without an
  ``if __name__ == "__main__":`` guard is refused in one line (it would otherwise re-execute in
  every worker and end in ``WorkerLost``); the same call under the guard, or inside a function
  the guarded block calls, runs.
"""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from tests.support.drawer3d import write_project

PREAMBLE = """
import json, sys
import tli_verify as tli
"""

SETUP = """
spec = tli.load_spec("specs/drawer.toml")
task = tli.load_task("tasks/drawer.toml")
model = tli.learn(task.demonstrate(seed=0), spec=spec, out="models/drawer.model.json")
tli.certify(model, out="certificates/drawer.cert.json")
"""

CAMPAIGN = """
config = tli.CampaignConfig(spec="specs/drawer.toml", examples={examples}, seed=3,
                            backend="{backend}", workers=2)
result = tli.run_campaign(config)
path, record = tli.write_campaign_evidence(config, result)
print(json.dumps({{"path": str(path), "record": record}}))
"""


def _script(folder: Path, name: str, body: str) -> Path:
    path = folder / name
    path.write_text(textwrap.dedent(body))
    return path


def _python(script: Path, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, str(script)], cwd=cwd, capture_output=True,
                          text=True, timeout=600)


@pytest.fixture(scope="module")
def project(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = write_project(tmp_path_factory.mktemp("pyuser"))
    for d in ("models", "certificates"):
        (root / d).mkdir(exist_ok=True)
    script = _script(root, "setup_models.py", PREAMBLE + SETUP)
    done = _python(script, root)
    assert done.returncode == 0, done.stderr[-2000:]
    return root


def test_python_evidence_records_the_campaign_that_ran(project: Path) -> None:
    body = PREAMBLE + "\nif __name__ == '__main__':\n" + textwrap.indent(
        CAMPAIGN.format(examples=30, backend="process"), "    ")
    done = _python(_script(project, "guarded.py", body), project)
    assert done.returncode == 0, done.stderr[-2000:]
    out = json.loads(done.stdout.strip().splitlines()[-1])
    path, record = project / out["path"], out["record"]
    assert path == project / "certificates" / "drawer.campaign.json"
    assert json.loads(path.read_text()) == record  # the record is the file's document
    settings = record["campaign"]["settings"]
    # the task's perturbation defaults, as the campaign ran them (tasks/drawer.toml)
    assert settings["window"] == 600 and settings["max_pushes"] == 3
    from tli_verify.verify.evidence import check_evidence

    check = check_evidence(path, min_examples=30)
    assert check.ok, check.problems


@pytest.mark.parametrize("layout", ["top-level", "function-called-at-top-level"])
def test_an_unguarded_script_is_refused_in_one_line(project: Path, layout: str) -> None:
    campaign = CAMPAIGN.format(examples=10, backend="process")
    if layout == "top-level":
        body = PREAMBLE + campaign
    else:
        body = PREAMBLE + "\ndef go():\n" + textwrap.indent(campaign, "    ") + "\ngo()\n"
    done = _python(_script(project, f"unguarded_{layout}.py", body), project)
    assert done.returncode != 0
    last = done.stderr.strip().splitlines()[-1]
    assert "if __name__ ==" in last and "guard" in last, done.stderr[-2000:]
    assert "WorkerLost" not in done.stderr


def test_a_guarded_function_call_and_a_serial_campaign_run(project: Path) -> None:
    campaign = CAMPAIGN.format(examples=5, backend="process")
    body = (PREAMBLE + "\ndef go():\n" + textwrap.indent(campaign, "    ")
            + '\nif __name__ == "__main__":\n    go()\n')
    done = _python(_script(project, "guarded_fn.py", body), project)
    assert done.returncode == 0, done.stderr[-2000:]
    serial = _python(_script(project, "serial.py", PREAMBLE + CAMPAIGN.format(
        examples=5, backend="serial")), project)
    assert serial.returncode == 0, serial.stderr[-2000:]


def test_a_config_that_is_not_the_result_s_is_refused(project: Path) -> None:
    body = PREAMBLE + textwrap.dedent("""
        from dataclasses import replace
        config = tli.CampaignConfig(spec="specs/drawer.toml", examples=5, backend="serial")
        result = tli.run_campaign(config)
        try:
            tli.write_campaign_evidence(replace(config, seed=9), result)
        except tli.TliError as exc:
            print("refused:", exc)
        """)
    done = _python(_script(project, "mismatch.py", body), project)
    assert done.returncode == 0, done.stderr[-2000:]
    assert "refused: config.seed is 9, the campaign ran with 0" in done.stdout


def test_write_campaign_evidence_is_public_and_documented() -> None:
    import tli_verify as tli
    from tli_verify.verify import evidence

    assert "write_campaign_evidence" in tli.__all__
    assert tli.write_campaign_evidence is evidence.write_campaign_evidence
    doc = evidence.write_campaign_evidence.__doc__ or ""
    assert "``path``" in doc and "``record``" in doc
    howto = (Path(__file__).resolve().parents[2] / "docs" / "howto" / "campaigns.md"
             ).read_text()
    assert "tli.write_campaign_evidence(config, result)" in howto
    assert 'if __name__ == "__main__":' in howto
