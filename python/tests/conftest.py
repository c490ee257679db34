"""Shared paths: the repository root and the published reference files
(../shared/reference from the root, as the Rust tests use them)."""

import os
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
REFERENCE = Path(os.environ.get("SAMARA_REFERENCE", ROOT.parent / "shared" / "reference"))
SPEC = ROOT / "models" / "alsomitra" / "alsomitra.spec"


def reference(name: str) -> Path:
    p = REFERENCE / name
    if not p.is_file():
        pytest.skip(f"reference file {p} not present")
    return p
