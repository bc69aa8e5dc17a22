"""The README's Python tour runs as written (against a fresh database folder)."""

import re
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[1] / "README.md"


@pytest.mark.slow
def test_readme_python_tour_runs(tmp_path, monkeypatch):
    text = README.read_text()
    tour = text[text.index("From Python:"):]
    code = re.search(r"```python\n(.*?)```", tour, re.S).group(1)
    monkeypatch.setenv("GRASPSIM_DB", str(tmp_path / "db"))
    ns: dict = {}
    exec(compile(code, "README.md", "exec"), ns)  # noqa: S102 - our own README
    assert ns["T_obj_wrist"].shape == (10, 4, 4)
    assert len(ns["result"].map) > 0 and len(ns["known"].map) > 0
    assert ns["known"].status.value == "complete" and len(ns["known"].parts) == 2
