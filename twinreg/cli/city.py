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
