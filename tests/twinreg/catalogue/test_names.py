"""References are unambiguous and names are plain text (issue 19): an all-digit name is refused (an auto-name gets
a prefix), ``id:N`` and ``name:X`` say which is meant, an ambiguous bare REF lists both, and names with control
characters are refused or printed as escapes."""

import shutil
import sqlite3

from typer.testing import CliRunner

from twinreg.cli import app


def _invoke(*args):
    return CliRunner().invoke(app, [str(a) for a in args])


def test_a_file_named_with_digits_gets_a_name_that_is_not_an_id(parametric_objs, tmp_path):
    lib = tmp_path / "lib"
    for stem, src in (("first", "demo_sedan"), ("2", "demo_suv")):
        dst = tmp_path / f"{stem}.obj"
        shutil.copy(parametric_objs[src], dst)
        res = _invoke("add-model", dst, "--library", lib)
        assert res.exit_code == 0, res.output
    res = _invoke("show-model", "name:model-2", "--library", lib, "--json")
    assert res.exit_code == 0, res.output
    assert '"id": 2' in res.stdout
    res = _invoke("add-model", parametric_objs["demo_coupe"], "--name", "3", "--library", lib)
    assert res.exit_code == 1 and "all digits" in res.output
    res = _invoke("update-model", "1", "--name", "42", "--library", lib)
    assert res.exit_code == 1 and "all digits" in res.output


def test_an_ambiguous_ref_lists_both_and_prefixes_choose(parametric_objs, tmp_path):
    """A catalogue from before the rule holds a model named "2" beside model id 2: the bare REF is refused."""
    from twinreg.catalogue.repository import Catalogue

    lib = tmp_path / "lib"
    cat = Catalogue(lib)
    cat.add(parametric_objs["demo_sedan"], name="sedan")
    cat.add(parametric_objs["demo_suv"], name="suv")
    cat.add(parametric_objs["demo_coupe"], name="coupe")
    cat.close()
    con = sqlite3.connect(lib / "catalogue.sqlite")
    con.execute("UPDATE ref_models SET name = '2' WHERE name = 'coupe'")
    con.commit()
    con.close()
    res = _invoke("remove-model", "2", "--yes", "--library", lib)
    assert res.exit_code == 1 and "ambiguous" in res.output and "id:2" in res.output and "name:2" in res.output
    assert len(Catalogue(lib).list()) == 3
    res = _invoke("remove-model", "name:2", "--yes", "--library", lib, "--json")
    assert res.exit_code == 0 and '"name": "2"' in res.stdout
    assert [r.name for r in Catalogue(lib).list()] == ["sedan", "suv"]
    res = _invoke("show-model", "2", "--library", lib, "--json")  # no longer ambiguous: the id
    assert res.exit_code == 0 and '"name": "suv"' in res.stdout
    assert _invoke("show-model", "id:9", "--library", lib).exit_code == 1


def test_names_with_control_characters_are_refused_and_old_ones_print_as_escapes(parametric_objs, tmp_path):
    from twinreg.catalogue.repository import Catalogue

    lib = tmp_path / "lib"
    Catalogue(lib).add(parametric_objs["demo_sedan"], name="sedan")
    for bad in ("two\nlines", "red\x1b[31mtext", " padded"):
        res = _invoke("update-model", "sedan", "--name", bad, "--library", lib)
        assert res.exit_code == 1 and "not a usable model name" in res.output, bad
        assert "\x1b" not in res.output and len(res.output.strip().splitlines()) == 1
    con = sqlite3.connect(lib / "catalogue.sqlite")
    con.execute("UPDATE ref_models SET name = 'evil' || char(27) || '[2J' || char(10) || 'x'")
    con.commit()
    con.close()
    res = _invoke("list-models", "--library", lib)
    assert res.exit_code == 0 and "\x1b" not in res.output and "evil\\x1b[2J\\nx" in res.output
