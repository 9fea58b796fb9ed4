"""The one version source: ``[project] version`` of ``pyproject.toml``, read back.

An installed tli-verify (a wheel, or ``pip install -e .``) has it in its distribution metadata
(:func:`importlib.metadata.version`). A source tree that was never installed (``PYTHONPATH=.``)
has no metadata: the version is then read from the ``pyproject.toml`` next to the package, and
is ``0+unknown`` only when neither exists. The version string is written nowhere else.

The version is information (``tli --version``, the ``tool`` block of certificates and
evidence); no check compares it. What a campaign means is versioned separately
(:data:`tli_verify.verify.evidence.CAMPAIGN_SEMANTICS`).
"""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

__all__ = ["DISTRIBUTION", "__version__"]

DISTRIBUTION = "tli-verify"


def _source_tree_version() -> str:
    """``[project] version`` of the checkout's ``pyproject.toml``, else ``0+unknown``."""
    import tomllib

    pyproject = Path(__file__).resolve().parent.parent / "pyproject.toml"
    try:
        with pyproject.open("rb") as f:
            project = tomllib.load(f).get("project", {})
    except (OSError, tomllib.TOMLDecodeError):
        return "0+unknown"
    found = project.get("version") if project.get("name") == DISTRIBUTION else None
    return found if isinstance(found, str) and found else "0+unknown"


try:
    __version__: str = version(DISTRIBUTION)
except PackageNotFoundError:
    __version__ = _source_tree_version()
