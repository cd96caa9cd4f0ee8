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


def _twin(n_objects: int, vertical: str | None) -> dict:
    objects = [{"id": f"obj{k}", "match": {"name": "golf", "rmse_m": 0.031, "confidence": 0.97, "ambiguous_with": [],
                                          "outside_tolerance": False} if k % 2 else None,
                "reason": "no catalogue model of this size", "reason_code": "no_model_of_this_size",
                "bearing_deg": 12.0 * k} for k in range(n_objects)]
    return {"scene": "park.laz", "objects": objects, "clustering": {"n_clusters": 2}, "matching": {"n_trials": 9},
            "timing_s": {"total": 3.25}, "georef": {"vertical_source": vertical}, "warnings": ["made on the day"]}


def test_a_run_ends_with_its_counts_objects_outcomes_and_files(tmp_path):
    from twinreg.export.summary import object_lines, twin_summary, warnings_of

    (tmp_path / "twin.json").write_text("{}")
    lines = twin_summary(_twin(3, "--vertical-crs"), tmp_path)
    assert lines[0] == "park.laz: 3 objects, 1 matched, 2 clusters, 9 registration trials, 3.25 s"
    assert lines[1] == "kinds: 3 unknown" and lines[2] == "models: 1 golf"  # counts by kind and model, always
    assert lines[-3].startswith("objects: 1 with a model (1 at confidence 0.5 or more); 2 without")
    assert lines[-2] == f"written to {tmp_path}: twin.json"
    assert lines[-1] == f"size of {tmp_path}: 0.0 MB; the largest: twin.json 0.0 MB"
    each = object_lines(_twin(3, "--vertical-crs"))  # said with -v, whatever the twin's size
    assert each[0] == "  obj0: no match: no catalogue model of this size, bearing 0.0 deg"
    assert each[1] == "  obj1: golf (3.1 cm; confidence 0.97), bearing 12.0 deg"
    many = twin_summary(_twin(500, "--vertical-crs") | {"grid": {"n_cells": 4}}, tmp_path)
    assert len(many) == 6 and many[0].endswith(", 4 cells") and len(object_lines(_twin(500, None))) == 500
    assert warnings_of(_twin(1, "--vertical-crs")) == ["warning: made on the day"]
    unknown = warnings_of(_twin(1, None))
    assert len(unknown) == 2 and "--vertical-crs" in unknown[1]
