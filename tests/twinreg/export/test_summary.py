"""The end of a run as its user reads it: the objects by outcome, every file written."""

from twinreg.export.summary import files_written, outcomes


def test_outcomes_count_models_and_reasons_most_common_first():
    objects = [{"match": {"confidence": 0.9}}, {"match": {"confidence": 0.2}}, {"match": {"confidence": None}},
               {"match": None, "reason_code": "no_model_of_this_size"},
               {"match": None, "reason_code": "model_too_tall"}, {"match": None, "reason_code": "model_too_tall"},
               {"match": None}]
    assert outcomes(objects) == ["3 with a model (1 at confidence 0.5 or more)",
                                 "2 without: the best model only fits sunk into the ground",
                                 "1 without: no catalogue model of their size", "1 without: other"]
    assert outcomes([]) == ["0 with a model (0 at confidence 0.5 or more)"]


def test_files_written_name_the_top_level_and_count_folders(tmp_path):
    (tmp_path / "tiles" / "scan").mkdir(parents=True)
    for name in ("tiles/tileset.json", "tiles/scan/a.glb", "tiles/scan/b.glb", "twin.json", ".twinreg-output.json"):
        (tmp_path / name).write_text("x")
    (tmp_path / ".cells").mkdir()
    (tmp_path / ".cells" / "c.npz").write_text("x")
    assert files_written(tmp_path) == ["tiles/ (3 files)", "twin.json"]
