"""docs/python.md's worked example is python/examples/quarter_car.py verbatim, and it runs as a
script on the session's model (so the example cannot rot)."""

from __future__ import annotations

import re
import subprocess
import sys

from conftest import ROOT


def test_the_doc_shows_the_example_verbatim() -> None:
    doc = (ROOT / "docs" / "python.md").read_text()
    example = (ROOT / "python" / "examples" / "quarter_car.py").read_text()
    blocks = re.findall(r"```python\n(.*?)```", doc, re.S)
    assert example in blocks


def test_the_example_runs(run, tmp_path) -> None:
    model = run.dir("train[algorithm=5]", "model.safetensors")
    calibration = run.dir("calibrate", "calibration.json").parent
    r = subprocess.run(
        [sys.executable, str(ROOT / "python" / "examples" / "quarter_car.py"), str(model), str(calibration), str(tmp_path)],
        cwd=ROOT, capture_output=True, text=True,
    )
    assert r.returncode == 0, r.stdout + r.stderr
    png = (tmp_path / "z_s.png").read_bytes()
    assert png.startswith(b"\x89PNG") and len(png) > 5000
    assert "ST" in r.stdout and "verdict" in r.stdout
