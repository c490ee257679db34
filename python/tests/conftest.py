"""Shared paths: the repository root and the published reference files
(../shared/reference from the root, as the Rust tests use them)."""

import os
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
REFERENCE = Path(os.environ.get("SAMARA_REFERENCE", ROOT.parent / "shared" / "reference"))
SPEC = ROOT / "models" / "alsomitra" / "alsomitra.spec"


def reference(name: str) -> Path:
    """A published reference file; a missing one fails the test naming it (the policy of
    samara-testkit: never a silent skip)."""
    p = REFERENCE / name
    if not p.is_file():
        pytest.fail(
            f"reference file {p} not found: the tests read the published case-study files "
            "from ../shared/reference beside the repository (or $SAMARA_REFERENCE)",
            pytrace=False,
        )
    return p
