"""The notebook-style example (python/examples/notebook.py) runs through the Python API
alone and passes its own checks: P1's critical value of the published naive network
(45.912, vacuous), the adversarial controller's reach verdict (proved) and, when torch
is installed, a freshly trained PyTorch 6-6-4-1 network's P1-P4 critical values
checked against PyTorch's own evaluation."""

import os
import subprocess
import sys

from conftest import ROOT, reference


def test_notebook_example_passes_its_checks(tmp_path):
    # Run from an unrelated folder: the script finds its files from its own path.
    reference("base_model_norm.onnx")
    reference("adversarial_model_denorm.onnx")
    script = ROOT / "python" / "examples" / "notebook.py"
    r = subprocess.run(
        [sys.executable, str(script)], capture_output=True, text=True, timeout=600, cwd=tmp_path,
        env={**os.environ, "PYTHONDONTWRITEBYTECODE": "1"},
    )
    assert r.returncode == 0, r.stdout + r.stderr
    assert "P1 critical ystar = 45.91195" in r.stdout
    assert "reach: proved" in r.stdout


def test_readme_python_example_runs_where_it_says():
    """README.md's Python example, run from the folder its first comment names (the
    repository root: its paths are relative to it), prints the typed result it shows."""
    import re

    reference("base_model_norm.onnx")
    text = (ROOT / "README.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, re.S)
    assert blocks, "README.md has no Python example"
    code = blocks[0]
    assert "Run from the repository root" in code
    r = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=300, cwd=ROOT,
        env={**os.environ, "PYTHONDONTWRITEBYTECODE": "1"},
    )
    assert r.returncode == 0, r.stdout + r.stderr
    lines = r.stdout.splitlines()
    assert lines[0].startswith("above 45.91") and lines[0].endswith("True"), r.stdout
    assert lines[1].startswith("CriticalResult(property='p1', parameter='ystar', holds='above'"), r.stdout
    assert "proved" in lines[2], r.stdout
