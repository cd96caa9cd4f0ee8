"""What kind of object a catalogue model is: its ``category``, lower-case, from the catalogue's own vocabulary
(any name of letters, digits and underscores; ``car`` when not given), and the plausible size of each known one,
for inferring a mesh file's unit and refusing an implausible one. Vehicles (their front told from the shape) and
the rest (their front the file's +X, unless ``--front``) differ in how a file is normalised."""

from __future__ import annotations

import re

from ..errors import CatalogueError

DEFAULT_CATEGORY = "car"
_NAME = re.compile(r"[a-z][a-z0-9_]{0,39}")

#: the longest extent (m) of a model of each category: (smallest, largest, typical); a unit is inferred to bring
#: the extent nearest the typical one within the range
SIZES = {
    "car": (2.5, 7.0, 4.5), "van": (3.5, 8.0, 5.2), "truck": (5.0, 20.0, 9.0), "bus": (7.0, 20.0, 12.0),
    "lamp_post": (2.0, 16.0, 7.0), "traffic_sign": (0.3, 5.0, 2.2), "hydrant": (0.3, 1.5, 0.8),
    "bin": (0.3, 2.5, 0.9), "bench": (0.8, 4.0, 1.8), "barrier": (0.5, 8.0, 3.0), "bollard": (0.2, 1.6, 0.9),
    "cone": (0.2, 1.3, 0.7), "tree": (1.0, 40.0, 8.0), "fence": (0.5, 80.0, 5.0), "shelter": (1.5, 12.0, 3.5),
    "mailbox": (0.4, 2.2, 1.1), "pole": (1.5, 25.0, 8.0), "kiosk": (1.0, 8.0, 2.5), "building": (3.0, 300.0, 15.0),
}
#: any other category
ANY_SIZE = (0.15, 80.0, 2.0)
#: categories whose front the normalisation tells from the shape (its lower end), as for cars
VEHICLES = frozenset({"car", "van", "truck", "bus"})


def check_category(value: str | None) -> str:
    """``value`` as a category (``car`` for None), or :class:`~twinreg.errors.CatalogueError` saying why not.

    >>> check_category(None), check_category("Lamp_Post")
    ('car', 'lamp_post')
    """
    if value is None:
        return DEFAULT_CATEGORY
    v = str(value).strip().lower()
    if not _NAME.fullmatch(v):
        raise CatalogueError(f"--category '{value}': a category is a lower-case word of letters, digits and "
                             "underscores (at most 40), e.g. lamp_post")
    return v


def size_range(category: str) -> tuple[float, float, float]:
    """(smallest, largest, typical) longest extent (m) of a model of ``category``."""
    return SIZES.get(category, ANY_SIZE)


def is_vehicle(category: str) -> bool:
    return category in VEHICLES
