"""Scenes are data, never code: the check of a user's Mitsuba XML scene before Sionna RT (Mitsuba) sees it.

Mitsuba turns an element's ``type`` into a plugin library to load and resolves file names through a search path
that starts at the current folder, so a scene someone sent could run native code (``<shape type="../x/evil"/>``
beside an ``evil.so``) or read any file of the machine. :func:`check_scene` needs no Sionna: it parses the scene
with ``defusedxml`` (no DTD, so no entities and no external references: no billion laughs, no XXE) and walks it
against an allowlist (docs/inputs.md, "Scenes"):

- elements: the objects of :data:`PLUGIN_TYPES` with one of the listed ``type`` names (the shapes, radio
  materials and visual BSDFs of Sionna's and Blender's scenes), the properties ``float``, ``integer``,
  ``boolean``, ``string``, ``rgb``, ``point``, ``vector``, ``spectrum`` (a value, not a file), ``transform`` with
  ``translate``/``rotate``/``scale``/``matrix``/``lookat``, ``ref``, ``default`` and ``include``; each with only
  the attributes Mitsuba reads from it;
- file references (a ``<string name="filename">``, an ``<include filename>``): relative paths that resolve, after
  symlinks, to an existing regular file inside the scene's folder; ``<include>`` depth at most
  :data:`MAX_INCLUDE_DEPTH`; a PLY mesh whose header declares more data than its file holds is refused (Mitsuba
  allocates what the header declares);
- ``$name`` parameters only in numbers, resolved from the scene's ``<default>`` elements;
- sizes: the XML files plus every file they name within ``size_limit("scene_bytes")``, shapes plus includes
  within ``size_limit("scene_shapes")`` (and at most :data:`ELEMENTS_PER_SHAPE` XML elements per allowed shape,
  nested at most :data:`MAX_NESTING` deep),
  and the primitive shapes (rectangle, cube, disk, sphere, cylinder under their ``to_world``) within
  ``size_limit("scene_extent_m")`` on every side.

Anything else raises :class:`UnsafeSceneError` with one line naming the file, the line, the element and the reason;
no message quotes a file the scene points at. What passes is returned as one XML string in which every file name
is the absolute path that was checked, every ``<include>`` is inlined and every parameter substituted, so what
Sionna loads is what was checked, whatever Mitsuba's search path holds.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path
import numpy as np
from defusedxml import DefusedXmlException
from defusedxml.ElementTree import DefusedXMLParser

from uamfleet.checks import ConfigError, check_size, size_limit

MESH_SHAPES = ("ply", "obj")
PRIMITIVE_SHAPES = ("rectangle", "cube", "disk", "sphere", "cylinder")
RADIO_MATERIALS = ("itu-radio-material", "radio-material", "absorber-radio-material")
# Blender's Mitsuba exporter writes these for a material; Sionna turns an ``itu_*`` one into a radio material.
VISUAL_BSDFS = (
    "diffuse", "twosided", "principled", "conductor", "roughconductor", "plastic", "roughplastic", "dielectric",
    "thindielectric", "roughdielectric",
)  # fmt: skip
PLUGIN_TYPES: dict[str, tuple[str, ...]] = {
    "shape": MESH_SHAPES + PRIMITIVE_SHAPES,
    "bsdf": RADIO_MATERIALS + VISUAL_BSDFS,
    "texture": ("bitmap",),
    # What an exported scene carries for rendering a picture; Sionna ignores them for radio.
    "integrator": ("path", "direct"),
    "emitter": ("constant",),
    "sensor": ("perspective",),
    "sampler": ("independent",),
    "film": ("hdrfilm",),
    "rfilter": ("gaussian", "box", "tent"),
}
"""Each object element a scene may hold and the plugin ``type`` names allowed for it (all built into Mitsuba or
registered by Sionna RT); any other type is refused, a path above all."""

NUMBER_PROPERTIES = ("float", "integer", "boolean", "rgb", "point", "vector", "spectrum")
TRANSFORM_OPS = ("translate", "rotate", "scale", "matrix", "lookat")
_ATTRIBUTES: dict[str, frozenset[str]] = {
    **{tag: frozenset({"type", "id", "name"}) for tag in PLUGIN_TYPES},
    "scene": frozenset({"version"}),
    **{tag: frozenset({"name", "value"}) for tag in ("float", "integer", "boolean", "string", "rgb", "spectrum")},
    "point": frozenset({"name", "value", "x", "y", "z"}),
    "vector": frozenset({"name", "value", "x", "y", "z"}),
    "transform": frozenset({"name"}),
    "translate": frozenset({"value", "x", "y", "z"}),
    "scale": frozenset({"value", "x", "y", "z"}),
    "rotate": frozenset({"value", "x", "y", "z", "angle"}),
    "matrix": frozenset({"value"}),
    "lookat": frozenset({"origin", "target", "up"}),
    "ref": frozenset({"id", "name"}),
    "default": frozenset({"name", "value"}),
    "include": frozenset({"filename", "name"}),
}
# Attributes whose value is a number (or numbers), where a $parameter may stand.
_NUMERIC_ATTRIBUTES = frozenset({"value", "x", "y", "z", "angle", "origin", "target", "up"})
MAX_INCLUDE_DEPTH = 8
_PLY_HEADER_BYTES = 1 << 16
_PLY_BYTES = {
    **dict.fromkeys(("char", "uchar", "int8", "uint8"), 1),
    **dict.fromkeys(("short", "ushort", "int16", "uint16"), 2),
    **dict.fromkeys(("int", "uint", "float", "int32", "uint32", "float32"), 4),
    **dict.fromkeys(("double", "float64"), 8),
}
MAX_NESTING = 32  # elements inside elements (a city scene needs about 5: scene, shape, bsdf, bsdf, texture)
ELEMENTS_PER_SHAPE = 16
"""XML elements allowed per shape of ``size_limit("scene_shapes")``: bounds the parsed tree of any XML file."""


class UnsafeSceneError(ConfigError):
    """A scene holds something that is not plain scene data (code, a file outside its folder, an entity) or is over
    a size limit; the message names the file, the line, the element and the reason, in one line."""


@dataclass(frozen=True)
class CheckedScene:
    """A scene that passed :func:`check_scene`: the XML to load, its folder, and what it holds."""

    xml: str
    folder: Path
    files: tuple[Path, ...]  # the XML files (the scene's first) and every file they name, resolved
    total_bytes: int
    shapes: int


def _short(value: str, limit: int = 60) -> str:
    """``value`` as a one-line literal of at most about ``limit`` characters (the scene's own text only)."""
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 4] + "...'"


class _Builder(ET.TreeBuilder):
    """A tree builder that records each element's line and bounds the number of elements (and shapes) as it goes."""

    def __init__(self, checker: _Checker, file: Path) -> None:
        super().__init__()
        self.checker, self.file = checker, file
        self.parser: DefusedXMLParser | None = None
        self.depth = 0

    def start(self, tag: str, attrs: dict[str, str]) -> ET.Element:
        element = super().start(tag, attrs)
        line = self.parser.parser.CurrentLineNumber if self.parser is not None else 0
        self.checker.where[element] = (self.file, line)
        self.checker.count(element, tag)
        self.depth += 1
        if self.depth > MAX_NESTING:
            raise self.checker.fail(element, f"is nested {self.depth} deep; elements nest at most {MAX_NESTING}")
        return element

    def end(self, tag: str) -> ET.Element:
        self.depth -= 1
        return super().end(tag)


class _Checker:
    """One check of one scene (module docstring); :meth:`run` returns the :class:`CheckedScene`."""

    def __init__(self, scene: Path) -> None:
        self.scene = scene
        self.folder = scene.parent
        self.where: dict[ET.Element, tuple[Path, int]] = {}
        self.files: list[Path] = []
        self.seen: set[Path] = set()
        self.total_bytes = 0
        self.elements = 0
        self.shapes = 0
        self.defaults: dict[str, str] = {}
        self.box_lo = np.full(3, np.inf)
        self.box_hi = np.full(3, -np.inf)
        self.extent_limit = size_limit("scene_extent_m")
        self.shape_limit = size_limit("scene_shapes")

    # -- errors and sizes -----------------------------------------------------------------------------------------

    def fail(
        self, element: ET.Element | None, reason: str, file: Path | None = None, line: int = 0
    ) -> UnsafeSceneError:
        if element is not None:
            file, line = self.where.get(element, (self.scene, 0))
            reason = f"<{element.tag}> {reason}"
        at = f", line {line}" if line else ""
        return UnsafeSceneError(f"scene {str(file or self.scene)!r}{at}: {reason}; nothing was loaded.")

    def add_bytes(self, path: Path, size: int) -> None:
        if path in self.seen:
            return  # a mesh that several shapes name is read once
        self.seen.add(path)
        self.total_bytes += size
        self.files.append(path)
        try:
            check_size("scene_bytes", self.total_bytes, f"scene {str(self.scene)!r} (up to {path.name!r})")
        except ConfigError as err:
            raise UnsafeSceneError(str(err)) from None

    def count(self, element: ET.Element, tag: str) -> None:
        self.elements += 1
        if tag in ("shape", "include"):
            self.shapes += 1
            try:
                check_size("scene_shapes", self.shapes, f"scene {str(self.scene)!r}")
            except ConfigError as err:
                raise UnsafeSceneError(str(err)) from None
        if self.elements > ELEMENTS_PER_SHAPE * self.shape_limit:
            raise self.fail(
                element,
                f"is element {self.elements:,}, over {ELEMENTS_PER_SHAPE} per allowed shape; if it is meant, raise "
                "UAMFLEET_MAX_SCENE_SHAPES=<n>",
            )

    # -- reading ----------------------------------------------------------------------------------------------------

    def parse(self, path: Path) -> ET.Element:
        """The root element of the XML file ``path`` (already checked to lie in the folder), parsed safely."""
        self.add_bytes(path, path.stat().st_size)
        builder = _Builder(self, path)
        parser = DefusedXMLParser(target=builder, forbid_dtd=True)
        builder.parser = parser
        try:
            with path.open("rb") as stream:
                while chunk := stream.read(1 << 20):
                    parser.feed(chunk)
            root: ET.Element = parser.close()
        except DefusedXmlException as err:
            raise self.fail(
                None,
                f"holds a DTD ({type(err).__name__}): entities and external references are never read; "
                "a scene is plain XML without <!DOCTYPE>",
                path,
                parser.parser.CurrentLineNumber,
            ) from None
        except ET.ParseError as err:
            raise self.fail(None, f"is not well-formed XML ({err})", path) from None
        return root

    def reference(self, element: ET.Element, value: str, base: Path, what: str) -> Path:
        """The file a reference ``value`` (relative to ``base``) names: an existing regular file in the folder."""
        if not value or "$" in value:
            raise self.fail(element, f"{what} {_short(value)} must be a plain file name (no $parameter)")
        if "\\" in value or Path(value).is_absolute() or (len(value) > 1 and value[1] == ":"):
            raise self.fail(
                element,
                f"{what} {_short(value)} must be a relative path with '/' inside the scene's folder, not absolute",
            )
        target = (base / value).resolve()
        if not target.is_relative_to(self.folder):
            raise self.fail(
                element,
                f"{what} {_short(value)} resolves outside the scene's folder {str(self.folder)!r} (after "
                "symlinks); a scene names only files inside its folder",
            )
        if not target.is_file():
            raise self.fail(
                element, f"{what} {_short(value)} is not a file inside the scene's folder (missing, a folder, ...)"
            )
        return target

    def expand(self, parent: ET.Element, file: Path, depth: int) -> None:
        """Replace every ``<include>`` under ``parent`` by what it includes, recursively."""
        k = 0
        while k < len(parent):
            child = parent[k]
            if child.tag != "include":
                self.expand(child, file, depth)
                k += 1
                continue
            self.check_attributes(child)
            if depth + 1 > MAX_INCLUDE_DEPTH:
                raise self.fail(child, f"nests includes deeper than {MAX_INCLUDE_DEPTH}")
            target = self.reference(child, child.get("filename", ""), file.parent, "filename")
            included = self.parse(target)
            self.expand(included, target, depth + 1)
            if included.tag == "scene":
                if included.attrib.keys() - {"version"}:
                    raise self.fail(included, "takes only a version attribute")
                new = list(included)
            else:
                if "name" in child.attrib:
                    included.set("name", child.get("name", ""))
                new = [included]
            parent[k : k + 1] = new
            k += len(new)

    def check_ply(self, element: ET.Element, path: Path) -> None:
        """Refuse a PLY mesh whose header declares more elements than its file can hold: Mitsuba allocates what
        the header declares before it reads the data (a 400-byte file declaring 2e9 vertices asks for 24 GB)."""
        with path.open("rb") as stream:
            head = stream.read(_PLY_HEADER_BYTES)
        end = head.find(b"end_header")
        if not head.startswith(b"ply") or end < 0:
            raise self.fail(element, f"names {path.name!r}, which is no PLY file (no 'ply' ... 'end_header' header)")
        lines = head[:end].decode("ascii", "replace").split("\n")
        binary = any(line.split()[:2] in (["format", "binary_little_endian"], ["format", "binary_big_endian"])
                     for line in lines)  # fmt: skip
        needed, count = 0, 0
        try:
            for words in (line.split() for line in lines):
                if words[:1] == ["element"]:
                    count = int(words[2])
                elif words[:1] == ["property"] and count:
                    # the least a value takes: its bytes in a binary file, a digit and a separator in text
                    size = _PLY_BYTES.get(words[2] if words[1] == "list" else words[1], 1) if binary else 2
                    needed += count * size
        except (IndexError, ValueError):
            raise self.fail(element, f"names {path.name!r}, whose PLY header is malformed") from None
        body = path.stat().st_size - (end + len("end_header"))
        if needed > body:
            raise self.fail(
                element,
                f"names {path.name!r}, whose header declares at least {needed:,} bytes of data but whose file holds "
                f"{max(body, 0):,}; Mitsuba would allocate what the header says",
            )

    # -- the walk ---------------------------------------------------------------------------------------------------

    def check_attributes(self, element: ET.Element) -> None:
        extra = sorted(element.attrib.keys() - _ATTRIBUTES[element.tag])
        if extra:
            raise self.fail(element, f"has the attribute {extra[0]!r}, which a scene's <{element.tag}> never takes")
        for key, value in element.attrib.items():
            if "$" in value and not (key in _NUMERIC_ATTRIBUTES and element.tag not in ("string", "default")):
                raise self.fail(element, f"has {key}={_short(value)}: $parameters may stand only in numbers")

    def substitute(self, element: ET.Element) -> None:
        """Replace each ``$name`` in a numeric attribute by its ``<default>``, longest names first (as Mitsuba)."""
        for key, value in element.attrib.items():
            if "$" not in value:
                continue
            for name in sorted(self.defaults, key=len, reverse=True):
                value = value.replace("$" + name, self.defaults[name])
            if "$" in value:
                raise self.fail(element, f"has {key}={_short(element.get(key, ''))} with no <default> for it")
            element.set(key, value)

    def collect_defaults(self, root: ET.Element) -> None:
        for element in root.iter("default"):
            self.check_attributes(element)
            name, value = element.get("name", ""), element.get("value", "")
            if not name or "$" in name or "$" in value:
                raise self.fail(element, "needs a plain name and a value without $")
            self.defaults.setdefault(name, value)

    def walk(self, element: ET.Element, parent: str) -> None:
        """Check ``element`` (inside a ``<parent>``; "" at the top) and everything under it, in document order."""
        tag = element.tag
        self.check_position(element, parent)
        self.check_attributes(element)
        self.substitute(element)
        if tag in PLUGIN_TYPES:
            self.check_type(element, parent)
        elif tag != "scene" and parent not in PLUGIN_TYPES and parent != "scene":
            raise self.fail(element, f"cannot stand inside <{parent}>")
        if tag == "string" and element.get("name", "").lower() == "filename":
            self.resolve_file(element)
        if tag == "transform":
            for op in element:
                self.check_attributes_of_op(op)
            return
        if tag not in PLUGIN_TYPES and tag != "scene" and len(element):
            raise self.fail(element[0], f"cannot stand inside <{tag}>")
        for child in element:
            self.walk(child, tag)
        if tag == "shape":
            self.place(element)
            self.check_ply_files(element)

    def check_position(self, element: ET.Element, parent: str) -> None:
        """Refuse an element a scene never holds, and a ``<scene>`` anywhere but at the top (``parent`` "")."""
        tag = element.tag
        if tag not in _ATTRIBUTES or tag == "include":
            raise self.fail(element, "is not an element a scene may hold (docs/inputs.md lists them)")
        if tag == "scene" and parent != "":
            raise self.fail(element, "may only be the file's top element")
        if tag != "scene" and parent == "":
            raise self.fail(element, "is the top element; a scene file's top element is <scene>")

    def resolve_file(self, element: ET.Element) -> None:
        """Point a ``<string name="filename">`` at the checked absolute path of its file, and count its bytes."""
        target = self.reference(element, element.get("value", ""), self.folder, "filename")
        self.add_bytes(target, target.stat().st_size)
        element.set("value", str(target))

    def check_ply_files(self, shape: ET.Element) -> None:
        """:meth:`check_ply` on the file of a ``<shape type="ply">``, walked already (its path checked, absolute)."""
        if shape.get("type") == "ply":  # whatever the file's name: Mitsuba reads it as PLY
            for child in shape.findall("string"):
                if child.get("name", "").lower() == "filename":
                    self.check_ply(child, Path(child.get("value", "")))  # the checked absolute path

    def check_type(self, element: ET.Element, parent: str) -> None:
        kind = element.get("type", "")
        if parent not in ("scene", *PLUGIN_TYPES):
            raise self.fail(element, f"cannot stand inside <{parent}>")
        if any(mark in kind for mark in ("/", "\\", "..", "\0")):
            raise self.fail(
                element, f"type {_short(kind)} is a path: a plugin type is a name, and paths would load code"
            )
        if kind not in PLUGIN_TYPES[element.tag]:
            raise self.fail(
                element,
                f"type {_short(kind)} is not one a city scene needs; allowed: {', '.join(PLUGIN_TYPES[element.tag])}",
            )

    def check_attributes_of_op(self, op: ET.Element) -> None:
        if op.tag not in TRANSFORM_OPS:
            raise self.fail(op, "cannot stand inside <transform> (translate, rotate, scale, matrix, lookat can)")
        self.check_attributes(op)
        self.substitute(op)
        if len(op):
            raise self.fail(op[0], f"cannot stand inside <{op.tag}>")

    # -- extents of the primitive shapes ----------------------------------------------------------------------------

    def numbers(self, element: ET.Element, key: str, count: int, default: float | None = None) -> list[float]:
        raw = element.get(key)
        if raw is None:
            if default is None:
                raise self.fail(element, f"needs {key}")
            return [default] * count
        try:
            values = [float(v) for v in raw.replace(",", " ").split()]
        except ValueError:
            raise self.fail(element, f"has {key}={_short(raw)}, not numbers") from None
        if len(values) == 1 and count > 1:
            values = values * count
        if len(values) != count or not all(math.isfinite(v) for v in values):
            raise self.fail(element, f"has {key}={_short(raw)}; it needs {count} finite numbers")
        return values

    def xyz(self, element: ET.Element, default: float) -> np.ndarray:
        if "value" in element.attrib:
            return np.array(self.numbers(element, "value", 3))
        return np.array([self.numbers(element, axis, 1, default)[0] for axis in "xyz"])

    def op_matrix(self, op: ET.Element) -> np.ndarray:
        matrix = np.eye(4)
        if op.tag == "translate":
            matrix[:3, 3] = self.xyz(op, 0.0)
        elif op.tag == "scale":
            matrix[:3, :3] = np.diag(self.xyz(op, 1.0))
        elif op.tag == "rotate":
            axis = self.xyz(op, 0.0)
            norm = float(np.linalg.norm(axis))
            if norm == 0.0:
                raise self.fail(op, "needs a rotation axis")
            x, y, z = axis / norm
            angle = math.radians(self.numbers(op, "angle", 1, 0.0)[0])
            cross = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
            matrix[:3, :3] = np.eye(3) + math.sin(angle) * cross + (1.0 - math.cos(angle)) * cross @ cross
        elif op.tag == "matrix":
            values = self.numbers(op, "value", len((op.get("value") or "").replace(",", " ").split()))
            if len(values) == 16:
                matrix = np.array(values).reshape(4, 4)
            elif len(values) == 9:
                matrix[:3, :3] = np.array(values).reshape(3, 3)
            else:
                raise self.fail(op, "needs 9 or 16 numbers")
        else:  # lookat: a rotation and a translation to origin
            matrix[:3, 3] = self.numbers(op, "origin", 3)
        return matrix

    def to_world(self, shape: ET.Element) -> np.ndarray:
        matrix = np.eye(4)
        for transform in shape.findall("transform"):
            if transform.get("name") == "to_world":
                matrix = np.eye(4)
                for op in transform:
                    matrix = self.op_matrix(op) @ matrix  # each operation applies after the ones before it
        return matrix

    def prop(self, shape: ET.Element, tag: str, name: str) -> ET.Element | None:
        for element in shape.findall(tag):
            if element.get("name") == name:
                return element
        return None

    def local_box(self, shape: ET.Element, kind: str) -> np.ndarray:
        """Corners of the primitive's box before ``to_world``."""
        if kind == "sphere":
            center = self.prop(shape, "point", "center")
            radius = self.prop(shape, "float", "radius")
            c = self.xyz(center, 0.0) if center is not None else np.zeros(3)
            r = abs(self.numbers(radius, "value", 1)[0]) if radius is not None else 1.0
            lo, hi = c - r, c + r
        elif kind == "cylinder":
            ends = [self.prop(shape, "point", name) for name in ("p0", "p1")]
            radius = self.prop(shape, "float", "radius")
            p0 = self.xyz(ends[0], 0.0) if ends[0] is not None else np.zeros(3)
            p1 = self.xyz(ends[1], 0.0) if ends[1] is not None else np.array([0.0, 0.0, 1.0])
            r = abs(self.numbers(radius, "value", 1)[0]) if radius is not None else 1.0
            lo, hi = np.minimum(p0, p1) - r, np.maximum(p0, p1) + r
        else:  # rectangle, disk: the unit square/disk at z = 0; cube: [-1, 1]^3
            depth = 1.0 if kind == "cube" else 0.0
            lo, hi = np.array([-1.0, -1.0, -depth]), np.array([1.0, 1.0, depth])
        return np.array([[(hi if (k >> a) & 1 else lo)[a] for a in range(3)] for k in range(8)])

    def place(self, shape: ET.Element) -> None:
        """Add a primitive shape's box to the scene's and refuse one that makes the scene too large."""
        kind = shape.get("type", "")
        if kind not in PRIMITIVE_SHAPES:
            return  # a mesh's extent is known once loaded (raytrace.scene_extent bounds it)
        corners = np.c_[self.local_box(shape, kind), np.ones(8)] @ self.to_world(shape).T
        lo, hi = corners[:, :3].min(axis=0), corners[:, :3].max(axis=0)
        self.box_lo, self.box_hi = np.minimum(self.box_lo, lo), np.maximum(self.box_hi, hi)
        side = float((self.box_hi - self.box_lo).max())
        if not math.isfinite(side) or side > self.extent_limit:
            raise self.fail(
                shape,
                f"makes the scene {side:,.0f} m wide (this shape spans {lo.round(1).tolist()} to "
                f"{hi.round(1).tolist()}), over the limit of {self.extent_limit:,} m; if it is meant, raise it with "
                "UAMFLEET_MAX_SCENE_EXTENT_M=<n>",
            )

    # -- all of it --------------------------------------------------------------------------------------------------

    def run(self) -> CheckedScene:
        root = self.parse(self.scene)
        if root.tag != "scene":
            raise self.fail(root, "is the top element; a scene file's top element is <scene>")
        self.expand(root, self.scene, 0)
        self.collect_defaults(root)
        self.strip_defaults(root)
        self.walk(root, "")
        return CheckedScene(
            xml=ET.tostring(root, encoding="unicode"),
            folder=self.folder,
            files=tuple(self.files),
            total_bytes=self.total_bytes,
            shapes=self.shapes,
        )

    def strip_defaults(self, element: ET.Element) -> None:
        for child in list(element):
            if child.tag == "default":
                element.remove(child)
            else:
                self.strip_defaults(child)


def check_scene(scene: str | Path) -> CheckedScene:
    """Check the Mitsuba XML scene file ``scene`` (module docstring) without loading anything of it into Mitsuba.

    :class:`UnsafeSceneError` (a ValueError) for anything outside the allowlist or over a size limit,
    ``FileNotFoundError`` when ``scene`` is no file.
    """
    path = Path(scene)
    if not path.is_file():
        kind = "is a folder" if path.is_dir() else "does not exist" if not path.exists() else "is not a regular file"
        raise FileNotFoundError(f"scene file {str(path)!r} {kind}; pass a Mitsuba XML file or a built-in scene's name")
    return _Checker(path.resolve()).run()
