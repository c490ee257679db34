"""The notebook-style example (python/examples/notebook.py) runs through the Python API
alone and passes its own checks: P1's critical value of the published naive network
(45.912, vacuous), the adversarial controller's reach verdict (proved) and, when torch
is installed, a freshly trained PyTorch 6-6-4-1 network's P1-P4 critical values
checked against PyTorch's own evaluation."""

import os
import subprocess
import sys

from conftest import ROOT, reference


def test_notebook_example_passes_its_checks():
    reference("base_model_norm.onnx")
    reference("adversarial_model_denorm.onnx")
    script = ROOT / "python" / "examples" / "notebook.py"
    r = subprocess.run(
        [sys.executable, str(script)], capture_output=True, text=True, timeout=600,
        env={**os.environ, "PYTHONDONTWRITEBYTECODE": "1"},
    )
    assert r.returncode == 0, r.stdout + r.stderr
    assert "P1 critical ystar = 45.91195" in r.stdout
    assert "reach: proved" in r.stdout
