"""City commands: simulate-city (build-twin on tiles lives with build-twin in scenes.py)."""

from __future__ import annotations

from datetime import datetime
from pathlib import Path
from typing import Annotated, Optional

import typer

from ._common import Command, JsonOpt, LibraryOpt, RunProgress, command_app, handled, info, print_json

app = command_app()


def _city_summary(truth: dict, out: Path, source: str, later: bool) -> dict:
    """simulate-city's JSON: the city's figures, and a later survey's events by kind."""
    doc = {k: truth.get(k) for k in ("crs", "tile_m", "density", "seed", "side_m", "n_points", "tiles", "date")}
    doc |= {"n_cars": len(truth["cars"]), "truth": str(out / "truth.json"), "models": source,
            "n_furniture": sum(1 for o in truth.get("others", []) if o["kind"].startswith("furniture:"))}
    if later:
        doc["events"] = {k: sum(1 for e in truth["events"] if e["event"] == k)
                         for k in ("same", "moved", "left", "replaced", "arrived")}
    return doc


@app.command("simulate-city", cls=Command)
@handled
def simulate_city_cmd(
    out: Annotated[Path, typer.Argument(help="Folder for the LAZ tiles and truth.json (replaced as a whole).")],
    km2: Annotated[float, typer.Option(help="Area of the city (km2).")] = 0.01,
    density: Annotated[Optional[float], typer.Option(
        help="Points per m2 of open ground (two airborne passes) [default: 150; with --epoch-of the earlier "
             "survey's].", show_default=False)] = None,
    tile: Annotated[float, typer.Option(help="Tile side (m).")] = 100.0,
    seed: Annotated[int, typer.Option(help="Seed (the city is deterministic).")] = 0,
    crs: Annotated[str, typer.Option(help="Projected CRS written in the headers.")] = "EPSG:28992",
    copc: Annotated[bool, typer.Option("--copc", help="Write COPC files (.copc.laz) instead of plain LAZ.")] = False,
    layout: Annotated[str, typer.Option(
        "--layout", help="streets (parked cars along streets, walls, trees, poles) or parks (dense car parks of "
                         "10-16 cars with a kerb, wall, tree, kiosk and lamp post).")] = "streets",
    epoch_of: Annotated[Optional[Path], typer.Option(
        "--epoch-of", help="A later survey of the city in this folder (an earlier simulate-city): its cars stay, "
                           "move, leave, are replaced or arrive, flown along other lines, offset by (0.10, -0.08, "
                           "0.10) m, a strip without returns; the events in truth.json. --seed seeds the changes.",
        show_default=False)] = None,
    date: Annotated[Optional[datetime], typer.Option(
        "--date", formats=["%Y-%m-%d"], help="The survey's date in the tiles' headers, YYYY-MM-DD [default: today; "
                                             "with --epoch-of, 91 days after the earlier one's].",
        show_default=False)] = None,
    furniture: Annotated[bool, typer.Option(
        "--furniture", help="Streets layout: also the catalogue's street furniture (its models of other kinds than "
                            "vehicles) on the pavements.")] = False,
    library: LibraryOpt = None,
    json_: JsonOpt = False,
):
    """A tiled city of LAZ files (CRS in their headers) and truth.json: streets of parked cars (the catalogue's
    models, or parametric cars when it is empty), walls, trees, poles, sloping ground, or dense car parks
    (--layout parks); or, with --epoch-of, a later survey of such a city."""
    from ..io.outdir import staged_folder
    from ..sim.city import city_furniture, city_models, simulate_city

    if layout not in ("streets", "parks"):
        from ..errors import ParameterError

        raise ParameterError(f"--layout must be streets or parks (got {layout!r})")
    models, names, source, sizes = city_models(library)
    if source != "catalogue":
        info("the catalogue is empty: the city's cars are the project's parametric ones")
    when = date.date().isoformat() if date else None
    with RunProgress() as bars, staged_folder(out, protect=[epoch_of] if epoch_of else (), kind="city") as stage:
        if epoch_of is not None:
            truth = _later(stage, epoch_of, models, names, sizes, density, seed, when, bars.update,
                           city_furniture(library))
        else:
            truth = simulate_city(stage, models, names, km2=km2, density=density or 150.0, tile=tile, seed=seed,
                                  crs=crs, progress=bars.update, copc=copc, date=when, kind=layout,
                                  furniture=city_furniture(library) if furniture else None)
    if json_:
        print_json(_city_summary(truth, out, source, later=epoch_of is not None))
    else:
        info(f"{out}: {len(truth['tiles'])} tiles, {truth['n_points']:,} points, {len(truth['cars'])} cars "
             f"({truth['side_m']:g} m square, {crs}); truth in {out / 'truth.json'}")


def _later(stage, earlier: Path, models, names, sizes, density, seed, date, progress, furniture) -> dict:
    from ..errors import SceneReadError
    from ..sim.city_epoch import simulate_later

    if not (earlier / "truth.json").is_file():
        raise SceneReadError(f"{earlier}: no truth.json; --epoch-of takes a folder written by simulate-city")
    try:
        return simulate_later(stage, earlier, models, names, sizes, density=density, seed=seed, date=date,
                              progress=progress, furniture=furniture)
    except ValueError as exc:
        raise SceneReadError(str(exc)) from exc


@app.command("simulate-street", cls=Command)
@handled
def simulate_street_cmd(
    out: Annotated[Path, typer.Argument(help="Folder for scan.laz, trajectory.csv and truth.json (replaced as a "
                                             "whole).")],
    platform: Annotated[str, typer.Option(
        "--platform", help="mobile (a van with two profile scanners crossed at 45 degrees, 2.4 m up: GPS time and "
                           "scan angle per point, the trajectory beside) or airborne (oblique passes).")] = "mobile",
    cars: Annotated[int, typer.Option("--cars", help="Cars parked along the kerb (the catalogue's in turn).")] = 8,
    speed: Annotated[float, typer.Option(help="The van's speed (m/s).")] = 8.0,
    density: Annotated[float, typer.Option(help="Airborne: points per m2 of open ground.")] = 150.0,
    seed: Annotated[int, typer.Option(help="Seed (the street is deterministic).")] = 0,
    crs: Annotated[str, typer.Option(help="Projected CRS written in the header.")] = "EPSG:28992",
    library: LibraryOpt = None,
    json_: JsonOpt = False,
):
    """A simulated street survey: cars parked along a kerb, the catalogue's street furniture on the pavement,
    facades, scanned from a van (--platform mobile) or from the air; scan.laz, trajectory.csv (mobile) and
    truth.json (every item's kind, model, position and how many returns it got)."""
    from ..errors import ParameterError
    from ..io.outdir import staged_folder
    from ..sim.city import city_furniture, city_models
    from ..sim.street import write_street

    if platform not in ("mobile", "airborne"):
        raise ParameterError(f"--platform must be mobile or airborne (got {platform!r})")
    if not 1 <= cars <= 200 or not 0.5 <= speed <= 40.0 or not 1.0 <= density <= 2000.0:
        raise ParameterError("--cars takes 1-200, --speed 0.5-40 m/s, --density 1-2000 pts/m2")
    models, names, source, _ = city_models(library)
    if source != "catalogue":
        info("the catalogue has no vehicles: the street's cars are the project's parametric ones")
    street_cars = [("car", n, m) for n, m in zip(names, models)]
    with staged_folder(out, kind="street") as stage:
        doc = write_street(stage, street_cars, city_furniture(library), platform=platform, n_cars=cars, seed=seed,
                           speed=speed, density=density, crs=crs)
    summary = {k: doc.get(k) for k in ("platform", "crs", "n_points", "seconds", "speed_m_s", "density", "seed")}
    summary |= {"n_items": len(doc["items"]), "scan": str(out / "scan.laz"), "truth": str(out / "truth.json")}
    if platform == "mobile":
        summary["trajectory"] = str(out / "trajectory.csv")
    if json_:
        print_json(summary)
    else:
        info(f"{out}: {doc['n_points']:,} points from the {platform} platform, {len(doc['items'])} items; truth in "
             f"{out / 'truth.json'}")
