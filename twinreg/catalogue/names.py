"""What a model's name may be, and how a REF (an id or a name) finds one model without ambiguity.

A name is what users type and what pages and terminals show: 1-200 characters, no control or format characters
(no newline, no terminal escape), no leading or trailing space, and never all digits (``2`` would read as the id
of another model). A REF is ``id:N``, ``name:TEXT``, or bare text: digits are an id and other text a name; a
catalogue written before names were checked may hold a model named ``2`` beside a model of id 2, and then the bare
REF is refused, listing both.
"""

from __future__ import annotations

import re
import unicodedata
from pathlib import Path

from ..errors import CatalogueError

MAX_NAME = 200
_HEX64 = re.compile(r"[0-9a-f]{64}")
#: Unicode categories a name may not hold: controls (newline, escape), format characters, line and paragraph
#: separators
_CONTROL = frozenset(("Cc", "Cf", "Zl", "Zp"))


def _is_control(c: str) -> bool:
    return unicodedata.category(c) in _CONTROL


def name_problem(name) -> str | None:
    """Why ``name`` cannot be a model's name, or None.

    >>> [name_problem(n) for n in ("audi_tt", "2", "a\\nb", " x", "")]
    [None, 'it is all digits and would read as a model id', 'it holds a control character', 'it starts or ends with a space', 'it is empty']
    """
    if not isinstance(name, str) or not name:
        return "it is empty"
    if len(name) > MAX_NAME:
        return f"it is longer than {MAX_NAME} characters"
    if name.isdigit():
        return "it is all digits and would read as a model id"
    if any(map(_is_control, name)):
        return "it holds a control character"
    if name != name.strip():
        return "it starts or ends with a space"
    if name.startswith(("id:", "name:")):
        return "it starts with id: or name:, which REF reserves"
    return None


#: the longest make, model, body class or tag
MAX_TEXT = 200


def text_problem(value) -> str | None:
    """Why ``value`` cannot be a model's make, model, body class or tag (shown in terminals, CSV, KML and pages),
    or None. Empty is allowed (the field is then unset).

    >>> [text_problem(v) for v in (None, "Mercedes-Benz", "a\x1b]52;c;ZXZpbA==\x07", "x" * 201)]
    [None, None, 'it holds a control character', 'it is longer than 200 characters']
    """
    if value is None or value == "":
        return None
    if not isinstance(value, str):
        return "it is not text"
    if len(value) > MAX_TEXT:
        return f"it is longer than {MAX_TEXT} characters"
    if any(map(_is_control, value)):
        return "it holds a control character"
    return None


def check_text(value, option: str, where: str = ""):
    """``value`` if it may be a make, model, body class or tag (``option``: the option that gave it, for the
    message), else :class:`CatalogueError` saying why."""
    why = text_problem(value)
    if why:
        raise CatalogueError(f"{where}{option} {printable(str(value))[:80]!r}: not usable ({why}); give plain text")
    return value


def check_name(name: str, where: str = "") -> str:
    """``name`` if it may name a model, else :class:`CatalogueError` saying why and what to do."""
    why = name_problem(name)
    if why:
        raise CatalogueError(f"{where}{printable(name)!s}: not a usable model name ({why}); give another --name")
    return name


def safe_auto_name(stem: str) -> str:
    """A usable name from a file's stem: control characters dropped, digits prefixed.

    >>> safe_auto_name("2"), safe_auto_name(" golf\\n")
    ('model-2', 'golf')
    """
    text = "".join(c for c in stem if not _is_control(c)).strip()[:MAX_NAME - 10]
    if not text or text.startswith(("id:", "name:")):
        text = "model" + (f"-{text}" if text else "")
    return f"model-{text}" if text.isdigit() else text


#: words that name a part or an export, not a design: a file named only by them (``body.dae``, ``base_link.dae``)
#: or holding ``chassis``/``body`` (``suv_chassis.obj``, ``gd250_Chassis.obj``) takes its folder's name
GENERIC_WORDS = frozenset({"body", "chassis", "model", "mesh", "meshes", "base", "link", "visual", "vis", "scene",
                           "untitled", "object", "default", "export", "exported", "main", "final", "new", "lod0",
                           "lod1", "high", "low", "collision", "car", "vehicle", "geometry", "part"})


def is_generic_stem(stem: str) -> bool:
    """Whether a file's stem names a part or an export rather than a design.

    >>> [is_generic_stem(s) for s in ("body", "base_link", "suv_chassis", "gd250_Chassis", "audi_tt", "Hybrid")]
    [True, True, True, True, False, False]
    """
    words = [w for w in re.split(r"[_\-\s.]+", stem.lower()) if w]
    return bool(words) and (all(w in GENERIC_WORDS or w.isdigit() for w in words) and not all(
        w.isdigit() for w in words) or bool({"chassis", "body"} & set(words)))


def preferred_stem(path, root=None, sole: bool = False) -> str:
    """The name a model file suggests: its folder's name when the file's own is generic (:func:`is_generic_stem`),
    or when ``sole`` (the only model file of a folder below the import's ``root``: ``toyota_prius/Hybrid.obj``);
    else its stem.

    >>> preferred_stem("cars/ford_fusion_2013/body.dae"), preferred_stem("x/audi_tt.obj")
    ('ford_fusion_2013', 'audi_tt')
    >>> preferred_stem("cars/toyota_prius/Hybrid.obj", root="cars", sole=True)
    'toyota_prius'
    """
    p = Path(path)
    parent = p.parent.name
    below_root = root is not None and p.parent != Path(root) and bool(parent)
    if parent and (is_generic_stem(p.stem) or (sole and below_root)):
        return parent
    return p.stem


def is_sha256(text) -> bool:
    """True for 64 lower-case hex characters (a catalogue file's content address)."""
    return isinstance(text, str) and _HEX64.fullmatch(text) is not None


def printable(text) -> str:
    """``text`` with control characters shown as escapes (a name printed to a terminal runs no escape code).

    >>> printable("a\\x1b[31mb\\n")
    'a\\\\x1b[31mb\\\\n'
    """
    s = str(text)
    if not any(map(_is_control, s)):
        return s
    return "".join(c.encode("unicode_escape").decode("ascii") if _is_control(c) else c for c in s)


def parse_ref(ref) -> tuple[str, str]:
    """``("id", "2")``, ``("name", "golf")`` or ``("either", "2")`` for bare digits.

    >>> parse_ref("id:2"), parse_ref("name:2"), parse_ref("2"), parse_ref("golf")
    (('id', '2'), ('name', '2'), ('either', '2'), ('name', 'golf'))
    """
    text = str(ref)
    if text.startswith("id:"):
        return "id", text[3:]
    if text.startswith("name:"):
        return "name", text[5:]
    return ("either" if text.isdigit() else "name"), text


#: the orders a listing of the catalogue offers (list-models --sort)
SORT_KEYS = ("id", "name", "length", "width", "height", "make", "class")
