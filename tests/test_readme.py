"""The README's Python API example runs as written, and its layout section names the packages that exist."""

import contextlib
import io
import re

import pytest

from tests.conftest import REPO


def test_the_python_example_runs():
    text = (REPO / "README.md").read_text(encoding="utf-8")
    (code,) = re.findall(r"```python\n(.*?)```", text, re.S)
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compile(code, "README.md", "exec"), {})
    printed = out.getvalue()
    models, = re.findall(r"^(\d+) models$", printed, re.M)
    matched, total = (int(v) for v in re.search(r"^(\d+) of (\d+) objects have a model$", printed, re.M).groups())
    assert int(models) >= 4 and total >= 4 and matched >= total - 1, printed


def test_the_layout_section_matches_the_tree():
    text = (REPO / "README.md").read_text(encoding="utf-8")
    layout = text[text.index("## Layout"):]
    packages = sorted(p.name for p in (REPO / "twinreg").iterdir() if (p / "__init__.py").is_file())
    for name in packages:
        assert f"  {name}/" in layout, name
    for top in ("cosco/", "migrations/", "tests/", "bench/", "docs/"):
        assert top in layout and (REPO / top.rstrip("/")).is_dir(), top


def test_the_wheel_names_every_package():
    tomllib = pytest.importorskip("tomllib")  # Python 3.11+

    listed = set(tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    tree = {".".join(p.relative_to(REPO).parts[:-1]) for root in ("twinreg", "cosco")
            for p in (REPO / root).rglob("__init__.py")}
    assert tree | {"twinreg.migrations"} == listed
