"""The notebook of docs/python.md runs as written."""
import os
import pathlib
import re

DOC = pathlib.Path(__file__).resolve().parents[2] / "docs" / "python.md"


def test_notebook_example_runs(tmp_path, capsys):
    text = DOC.read_text(encoding="utf-8")
    section = text[text.index("## Notebook"):text.index("## Pipelines")]
    blocks = re.findall(r"```python\n(.*?)```", section, re.S)
    assert len(blocks) >= 4
    cwd = os.getcwd()
    os.chdir(tmp_path)
    try:
        exec(compile("\n".join(blocks), str(DOC), "exec"), {"__name__": "notebook"})
    finally:
        os.chdir(cwd)
    out = capsys.readouterr().out
    assert "skeleton voxels" in out and "branches by type" in out and "edge 0:" in out
