"""The checks every reader makes: a stranger's JSON read only within its size and nesting, one line naming the
file and the fix otherwise."""

from __future__ import annotations

import pytest

from twinreg.errors import CompareError
from twinreg.io._files import read_json_doc


def test_json_within_its_limits_is_read(tmp_path):
    (tmp_path / "ok.json").write_text('{"a": [1, 2, {"b": null}]}')
    assert read_json_doc(tmp_path / "ok.json", 1024, CompareError, "rerun") == {"a": [1, 2, {"b": None}]}


@pytest.mark.parametrize("text,words", [
    ("[" * 100_000 + "]" * 100_000, "nested deeper"),
    ("{not json", "not valid JSON"),
    (b"\xff\xfe{}", "not valid JSON"),
])
def test_json_that_is_not_data_is_one_line(tmp_path, text, words):
    path = tmp_path / "bad.json"
    path.write_bytes(text if isinstance(text, bytes) else text.encode())
    with pytest.raises(CompareError, match=words) as err:
        read_json_doc(path, 10 ** 7, CompareError, "rerun build-twin")
    assert str(path) in str(err.value) and "rerun build-twin" in str(err.value) and "\n" not in str(err.value)


def test_a_file_over_the_cap_is_not_read(tmp_path):
    path = tmp_path / "big.json"
    with open(path, "wb") as fh:
        fh.truncate(5 * 2 ** 20 + 1)  # sparse: nothing to read, and nothing is
    with pytest.raises(CompareError, match="5 MB, larger than any such file twinreg writes"):
        read_json_doc(path, 5 * 2 ** 20, CompareError, "rerun")
