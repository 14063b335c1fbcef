"""docs/python.md's worked example runs as written (its own asserts check
both fits), so the page cannot rot."""

import os
import re

from conftest import SOURCE_DIR


def test_worked_example_runs(monkeypatch):
    page = (SOURCE_DIR / "docs" / "python.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", page, re.S)
    assert len(blocks) == 1
    monkeypatch.chdir(SOURCE_DIR)  # the example runs from xgauge's folder
    exec(compile(blocks[0], "docs/python.md", "exec"), {"__name__": "docs_python"})
