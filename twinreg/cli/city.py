"""City commands: simulate-city (build-twin on tiles lives with build-twin in scenes.py)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from ._common import JsonOpt, LibraryOpt, RunProgress, handled, info, print_json

app = typer.Typer()


@app.command("simulate-city")
@handled
def simulate_city_cmd(
    out: Annotated[Path, typer.Argument(help="Folder for the LAZ tiles and truth.json (replaced as a whole).")],
    km2: Annotated[float, typer.Option(help="Area of the city (km2).")] = 0.01,
    density: Annotated[float, typer.Option(help="Points per m2 of open ground (two airborne passes).")] = 150.0,
    tile: Annotated[float, typer.Option(help="Tile side (m).")] = 100.0,
    seed: Annotated[int, typer.Option(help="Seed (the city is deterministic).")] = 0,
    crs: Annotated[str, typer.Option(help="Projected CRS written in the headers.")] = "EPSG:28992",
    copc: Annotated[bool, typer.Option("--copc", help="Write COPC files (.copc.laz) instead of plain LAZ.")] = False,
    library: LibraryOpt = None,
    json_: JsonOpt = False,
):
    """A tiled city of LAZ files (CRS in their headers) and truth.json: streets of parked cars (the catalogue's
    models, or parametric cars when it is empty), walls, trees, poles, sloping ground."""
    from ..io.outdir import staged_folder
    from ..sim.city import city_models, simulate_city

    models, names, source = city_models(library)
    if source != "catalogue":
        info("the catalogue is empty: the city's cars are the project's parametric ones")
    with RunProgress() as bars, staged_folder(out) as stage:
        truth = simulate_city(stage, models, names, km2=km2, density=density, tile=tile, seed=seed, crs=crs,
                              progress=bars.update, copc=copc)
    doc = {k: truth[k] for k in ("crs", "tile_m", "density", "seed", "side_m", "n_points", "tiles")}
    doc |= {"n_cars": len(truth["cars"]), "truth": str(out / "truth.json"), "models": source}
    if json_:
        print_json(doc)
    else:
        info(f"{out}: {len(truth['tiles'])} tiles, {truth['n_points']:,} points, {len(truth['cars'])} cars "
             f"({truth['side_m']:g} m square, {crs}); truth in {out / 'truth.json'}")
