"""Ray-traced SINR maps of any city with Sionna RT (the optional extra ``rt``: ``pip install -e '.[rt]'``).

A :class:`~uamfleet.radio.radio_map.RadioMap` is computed from a 3-D scene, a built-in Sionna scene by name
(``"munich"``, ``"etoile"``, ``"florence"``, ``"san_francisco"``, ``"simple_street_canyon"``, ..., or
``"empty"``: free space) or a user's Mitsuba XML (OpenStreetMap -> Blender -> Mitsuba export), on a horizontal
measurement plane at the flight altitude. Sionna's :class:`sionna.rt.RadioMapSolver` gives each GBS's path gain
averaged over each cell (Monte-Carlo rays, LoS + specular reflections + refraction up to ``max_depth``
interactions); the SINR is the best server's, with every other GBS interfering (scaled by its ``loading``) plus
thermal noise, as in the Berlin WinProp map and :func:`uamfleet.radio.channel_3gpp.expected_sinr_db`.

A user's XML scene is data, never code: :mod:`uamfleet.radio.scene_check` checks it against an allowlist before
Sionna sees it, and Sionna loads the checked XML (docs/inputs.md, "Scenes"). The map's area (at most
``scene_extent_m`` on a side) and raster (at most ``map_cells`` cells) are bounded before anything is allocated.

Frame: the map's usual one (``radio_map.py``): world (0, 0) is the centre of the raster's first cell (min x,
min y of the measurement area), x east = the scene's x, y north = the scene's y, arrays indexed ``[ix, iy]``.
``scene_origin_m`` in the provenance is the scene point of world (0, 0), so ``scene = world + scene_origin_m``.

Defaults (the paper's and TR 36.777's, as in ``channel_3gpp.py`` and the packaged ``detroit_3gpp`` map):
2 GHz carrier, 40 dBm per GBS, GBS 20 m tall, 10 MHz bandwidth, 9 dB noise figure (-95 dBm noise), every GBS
fully loaded. Antenna: one isotropic, vertically polarised element per GBS, no tilt (TR 36.777's UMi-AV path
loss, which the synthetic maps use, has no antenna gain either); ``antenna_pattern="tr38901"`` gives the
3GPP sector element (8 dBi, 65 degree beams) pointed along ``azimuth_deg`` and tilted down by ``downtilt_deg``.

Automatic GBS placement (:func:`grid_base_stations`), when no GBS are given: a square grid of spacing
``gbs_spacing_m`` (default 750 m: Berlin's density, 19 GBS on 10.6 km^2) laid over the measurement area,
``round(width / spacing)`` columns (at least 1) and as many rows likewise, one GBS at the centre of each grid
cell; its height is ``gbs_height_m`` (20 m) or, where a building is taller, the roof under the site plus a
3 m mast (``GBS_MAST_M``), so that no GBS sits inside a building.

Saved maps (:func:`save_radio_map_npz` / :func:`read_radio_map_npz`, also through
``uamfleet.load_radio_map("munich.npz")``) are plain ``.npz`` files with the raster, the GBS and a JSON
provenance (scene, GBS, parameters, sionna-rt version, seed); reading one needs no Sionna.
"""

from __future__ import annotations

import dataclasses
import importlib.metadata
import io
import json
import math
import os
import re
import time
import zipfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from uamfleet.checks import check_number, check_size, size_limit
from uamfleet.io import write_bytes_atomic
from uamfleet.radio.channel_3gpp import DEFAULT_BANDWIDTH_MHZ, DEFAULT_NOISE_FIGURE_DB, noise_power_dbm
from uamfleet.radio.radio_map import BaseStation, RadioMap, base_station_tuple, check_map_size
from uamfleet.radio.scene_check import check_scene

EMPTY_SCENE = "empty"  # free space: no object at all (the physics check against Friis)
ANTENNA_PATTERNS: tuple[str, ...] = ("iso", "dipole", "hw_dipole", "tr38901")  # Sionna's registered patterns
DEFAULT_CARRIER_GHZ = 2.0  # the paper's maps (Berlin's WinProp GBS: 2.1 GHz); channel_3gpp's default
DEFAULT_POWER_DBM = 40.0
DEFAULT_GBS_HEIGHT_M = 20.0
DEFAULT_GBS_SPACING_M = 750.0
GBS_MAST_M = 3.0
DEFAULT_SAMPLES_PER_TX = 10**7
DEFAULT_MAX_DEPTH = 3
NPZ_FORMAT = "uamfleet-radio-map/1"
_BS_FIELDS = ("x_m", "y_m", "height_m", "power_dbm", "frequency_mhz", "loading")


class RayTracingUnavailableError(ImportError):
    """Sionna RT is not installed (or cannot start); the message says how to install it."""


@dataclass(frozen=True)
class RayTracingParams:
    """The radio parameters of a ray-traced map; the defaults are the paper's / TR 36.777's (module docstring)."""

    carrier_ghz: float = DEFAULT_CARRIER_GHZ
    power_dbm: float = DEFAULT_POWER_DBM  # per GBS, for the automatically placed ones
    gbs_height_m: float = DEFAULT_GBS_HEIGHT_M  # automatically placed GBS (never below a roof + GBS_MAST_M)
    gbs_spacing_m: float = DEFAULT_GBS_SPACING_M  # grid of automatically placed GBS
    antenna_pattern: str = "iso"
    downtilt_deg: float = 0.0  # positive: boresight below the horizon
    azimuth_deg: float = 0.0  # boresight direction, counter-clockwise from east (x)
    noise_figure_db: float = DEFAULT_NOISE_FIGURE_DB
    bandwidth_mhz: float = DEFAULT_BANDWIDTH_MHZ
    samples_per_tx: int = DEFAULT_SAMPLES_PER_TX  # rays per GBS (Monte-Carlo: more is smoother and slower)
    max_depth: int = DEFAULT_MAX_DEPTH  # interactions (reflections/refractions) per ray
    seed: int = 42

    def __post_init__(self) -> None:
        positive = ("carrier_ghz", "gbs_spacing_m", "bandwidth_mhz")
        for name in (*positive, "power_dbm", "gbs_height_m", "downtilt_deg", "azimuth_deg", "noise_figure_db"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ValueError(f"RayTracingParams.{name} must be a finite number, got {value!r}")
            if name in positive and value <= 0:
                raise ValueError(f"RayTracingParams.{name} must be > 0, got {value!r}")
        if self.antenna_pattern not in ANTENNA_PATTERNS:
            raise ValueError(
                f"antenna_pattern {self.antenna_pattern!r} is unknown; use one of {', '.join(ANTENNA_PATTERNS)}"
            )
        for name, low in (("samples_per_tx", 1), ("max_depth", 0), ("seed", 0)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < low:
                raise ValueError(f"RayTracingParams.{name} must be an integer >= {low}, got {value!r}")

    @property
    def noise_dbm(self) -> float:
        """Thermal noise over the bandwidth plus the noise figure (10 MHz, 9 dB -> -95.0 dBm)."""
        return noise_power_dbm(self.bandwidth_mhz, self.noise_figure_db)


@dataclass(frozen=True)
class Extent:
    """An axis-aligned rectangle of the scene's ground plane, in the scene's coordinates (metres)."""

    x_min: float
    y_min: float
    x_max: float
    y_max: float

    def __post_init__(self) -> None:
        values = (self.x_min, self.y_min, self.x_max, self.y_max)
        if not all(math.isfinite(float(v)) for v in values) or self.x_max <= self.x_min or self.y_max <= self.y_min:
            raise ValueError(
                f"extent {values} must be finite with x_min < x_max and y_min < y_max (scene metres); "
                "pass (x_min, y_min, x_max, y_max)"
            )


# -- Sionna: import, scenes -----------------------------------------------------------------------------------


def _sionna_rt() -> Any:
    """``sionna.rt``, imported on first use (the module itself imports without Sionna)."""
    try:
        import sionna.rt
    except ImportError as err:
        raise RayTracingUnavailableError(
            f"ray-traced maps need Sionna RT ({err}); install the extra: pip install -e '.[rt]' "
            "(or bash scripts/setup.sh --rt, which also installs the LLVM that Dr.Jit needs)"
        ) from err
    return sionna.rt


def sionna_version() -> str:
    try:
        return importlib.metadata.version("sionna-rt")
    except importlib.metadata.PackageNotFoundError:
        return "not installed"


def builtin_scenes() -> tuple[str, ...]:
    """Names of Sionna's built-in scenes (``sionna.rt.scene.<name>`` XML files) and ``"empty"``."""
    scene_module = _sionna_rt().scene
    names = [n for n, v in vars(scene_module).items() if isinstance(v, str) and v.endswith(".xml")]
    return (EMPTY_SCENE, *sorted(names))


def load_scene(scene: str | os.PathLike[str]) -> Any:
    """A Sionna scene: a built-in one by name (:func:`builtin_scenes`) or a Mitsuba XML file by path.

    A file is checked first (:func:`uamfleet.radio.scene_check.check_scene`: data only, every file it names inside
    its folder, bounded sizes) and Sionna loads the checked XML, never the file itself; a built-in scene is
    Sionna's own and trusted.
    """
    if isinstance(scene, str) and scene == EMPTY_SCENE:
        return _sionna_rt().load_scene()
    if isinstance(scene, str) and not scene.endswith(".xml"):
        rt = _sionna_rt()
        if scene not in builtin_scenes():
            raise ValueError(
                f"scene {scene!r} is neither a built-in Sionna scene ({', '.join(builtin_scenes())}) nor a "
                "Mitsuba .xml file; pass one of those names or the path to your scene's XML"
            )
        return rt.load_scene(getattr(rt.scene, scene))
    checked = check_scene(Path(scene))  # before Sionna (Mitsuba) is even imported
    rt = _sionna_rt()
    try:
        return rt.load_scene_from_string(checked.xml)
    except RuntimeError as err:  # e.g. a broken mesh inside the folder: Mitsuba's reason, in one line
        reason = re.sub(r"\[[\w.]+:\d+\] |At string \(line \d+, col \d+\): ", "", " ".join(str(err).split()))
        raise ValueError(
            f"scene {str(checked.folder / Path(scene).name)!r} passed the scene check but Sionna could not load it: "
            f"{reason[:300]}"
        ) from None


def scene_extent(scene: Any) -> Extent:
    """The scene's ground-plane bounding box; a ValueError for a scene without objects (pass an extent)."""
    box = scene.mi_scene.bbox()
    lo, hi = [float(v) for v in box.min][:2], [float(v) for v in box.max][:2]
    if not all(math.isfinite(v) for v in (*lo, *hi)) or hi[0] <= lo[0] or hi[1] <= lo[1]:
        raise ValueError("the scene has no objects to take the map's area from; pass extent=(x0, y0, x1, y1)")
    area = Extent(lo[0], lo[1], hi[0], hi[1])
    check_extent(area, "the scene's bounding box (the map's default area)")
    return area


def check_extent(area: Extent, what: str) -> None:
    """Refuse an area with a side over ``size_limit("scene_extent_m")`` (docs/inputs.md)."""
    side = max(area.x_max - area.x_min, area.y_max - area.y_min)
    limit = size_limit("scene_extent_m")
    if side > limit:
        raise ValueError(
            f"{what} {dataclasses.astuple(area)} is {side:,.0f} m wide, over the limit of {limit:,} m on a side; "
            "pass a smaller extent, or if it is meant raise the limit with UAMFLEET_MAX_SCENE_EXTENT_M=<n>"
        )


def surface_height_m(scene: Any, xy: Sequence[tuple[float, float]]) -> np.ndarray:
    """Height of the highest surface (roof or ground) under each scene point ``(x, y)``; 0 where nothing is."""
    import mitsuba as mi

    top = float(scene.mi_scene.bbox().max[2]) if math.isfinite(float(scene.mi_scene.bbox().max[2])) else 0.0
    heights = np.zeros(len(xy))
    for k, (x, y) in enumerate(xy):
        ray = mi.Ray3f(mi.Point3f(x, y, top + 10.0), mi.Vector3f(0.0, 0.0, -1.0))
        hit = scene.mi_scene.ray_intersect(ray)
        if bool(hit.is_valid()[0]):
            heights[k] = float(hit.p.z[0])
    return heights


# -- the map's frame and its GBS --------------------------------------------------------------------------------


@dataclass(frozen=True)
class MapGrid:
    """The raster: ``shape`` cells of ``cell_m`` whose first centre is the scene point ``scene_origin_m``."""

    shape: tuple[int, int]
    cell_m: float
    scene_origin_m: tuple[float, float]

    @classmethod
    def covering(cls, extent: Extent, cell_m: float) -> MapGrid:
        """The cells of ``cell_m`` that cover ``extent`` from its min corner (the last ones reach past it)."""
        cell_m = check_number("cell_m", cell_m, positive=True)
        width, height = extent.x_max - extent.x_min, extent.y_max - extent.y_min
        nx = max(2, math.ceil(width / cell_m - 1e-9))
        ny = max(2, math.ceil(height / cell_m - 1e-9))
        # Before anything is allocated for it: the ray tracer's raster (and Dr.Jit's) has one value per cell.
        check_size("map_cells", nx * ny, f"a map of {width:g} m x {height:g} m on {cell_m:g} m cells", 8.0)
        return cls((nx, ny), float(cell_m), (extent.x_min + cell_m / 2, extent.y_min + cell_m / 2))

    def plane_center(self, altitude_m: float) -> tuple[float, float, float]:
        """Scene point at the middle of the measurement plane (Sionna's ``center``)."""
        (nx, ny), (ox, oy) = self.shape, self.scene_origin_m
        return (ox + (nx - 1) * self.cell_m / 2, oy + (ny - 1) * self.cell_m / 2, altitude_m)


def grid_base_stations(
    scene: Any, grid: MapGrid, params: RayTracingParams = RayTracingParams()
) -> tuple[BaseStation, ...]:
    """GBS on a square grid over the map (module docstring's rule), in the map's frame."""
    (nx, ny), cell = grid.shape, grid.cell_m
    width, height = nx * cell, ny * cell
    cols = max(1, round(width / params.gbs_spacing_m))
    rows = max(1, round(height / params.gbs_spacing_m))
    # World (0, 0) is the first cell's centre, so the area runs from -cell/2 to width - cell/2.
    sites = [
        ((i + 0.5) * width / cols - cell / 2, (j + 0.5) * height / rows - cell / 2)
        for j in range(rows)
        for i in range(cols)
    ]
    ox, oy = grid.scene_origin_m
    roofs = surface_height_m(scene, [(x + ox, y + oy) for x, y in sites])
    return tuple(
        BaseStation(
            x_m=x,
            y_m=y,
            height_m=max(params.gbs_height_m, float(roof) + GBS_MAST_M),
            power_dbm=params.power_dbm,
            frequency_mhz=params.carrier_ghz * 1e3,
            name=f"GBS {k}",
        )
        for k, ((x, y), roof) in enumerate(zip(sites, roofs, strict=True))
    )


# -- path gains and SINR ------------------------------------------------------------------------------------------


def best_server_sinr_db(received_mw: np.ndarray, loading: np.ndarray, noise_mw: float) -> np.ndarray:
    """``max_m S_m / (sum_{m' != m} l_m' S_m' + N)`` in dB over the first axis of ``received_mw [M, ...]``.

    NaN where no GBS reaches the cell at all (no ray arrived: not computed, an outage for the planners).
    """
    load = np.asarray(loading, dtype=np.float64).reshape((-1,) + (1,) * (received_mw.ndim - 1))
    interference = (load * received_mw).sum(axis=0)
    others = np.maximum(interference[None] - load * received_mw, 0.0)  # round-off can dip below 0
    best = (received_mw / (others + noise_mw)).max(axis=0)
    with np.errstate(divide="ignore"):
        return np.where(received_mw.max(axis=0) > 0, 10.0 * np.log10(best), np.nan)


def _add_transmitters(scene: Any, stations: Sequence[BaseStation], grid: MapGrid, params: RayTracingParams) -> None:
    rt = _sionna_rt()
    import mitsuba as mi

    scene.frequency = params.carrier_ghz * 1e9
    scene.bandwidth = params.bandwidth_mhz * 1e6
    scene.tx_array = rt.PlanarArray(num_rows=1, num_cols=1, pattern=params.antenna_pattern, polarization="V")
    scene.rx_array = rt.PlanarArray(num_rows=1, num_cols=1, pattern="iso", polarization="V")
    for name in list(scene.transmitters):
        scene.remove(name)
    ox, oy = grid.scene_origin_m
    # Sionna's orientation (alpha, beta, gamma) rotates about z, then y: beta > 0 turns boresight x downwards.
    orientation = mi.Point3f(math.radians(params.azimuth_deg), math.radians(params.downtilt_deg), 0.0)
    for k, bs in enumerate(stations):
        position = mi.Point3f(bs.x_m + ox, bs.y_m + oy, bs.height_m)
        scene.add(rt.Transmitter(f"gbs{k}", position=position, orientation=orientation, power_dbm=bs.power_dbm))


def path_gains(
    scene: Any, stations: Sequence[BaseStation], grid: MapGrid, altitude_m: float, params: RayTracingParams
) -> np.ndarray:
    """``[M, nx, ny]`` linear path gain of each GBS averaged over each cell of ``grid`` at ``altitude_m``."""
    rt = _sionna_rt()
    import mitsuba as mi

    _add_transmitters(scene, stations, grid, params)
    (nx, ny), cell = grid.shape, grid.cell_m
    radio_map = rt.RadioMapSolver()(
        scene,
        center=mi.Point3f(*grid.plane_center(altitude_m)),
        orientation=mi.Point3f(0.0, 0.0, 0.0),
        size=mi.Point2f(nx * cell, ny * cell),
        cell_size=mi.Point2f(cell, cell),
        samples_per_tx=params.samples_per_tx,
        max_depth=params.max_depth,
        seed=params.seed,
    )
    gains = np.array(radio_map.path_gain.numpy(), dtype=np.float64)  # [M, rows = y, columns = x]
    if gains.shape != (len(stations), ny, nx):
        raise RuntimeError(f"Sionna returned path gains of shape {gains.shape}, expected {(len(stations), ny, nx)}")
    return np.ascontiguousarray(gains.transpose(0, 2, 1))  # [M, ix, iy]


def _checked_request(
    altitude_m: float, extent: Extent | tuple[float, float, float, float] | None, cell_m: float
) -> Extent | None:
    """The altitude, then the measurement area (None: the scene's box) and its raster, checked before the scene
    is loaded; the area as an :class:`Extent`."""
    if not (math.isfinite(altitude_m) and altitude_m > 0):
        raise ValueError(f"altitude_m must be > 0 (the flight altitude, e.g. 100), got {altitude_m!r}")
    given = None if extent is None else extent if isinstance(extent, Extent) else Extent(*extent)
    if given is not None:
        check_extent(given, "the extent")
        MapGrid.covering(given, cell_m)
    return given


def _sinr_of_gains(gains: np.ndarray, stations: Sequence[BaseStation], params: RayTracingParams) -> np.ndarray:
    """``[nx, ny]`` best-server SINR (dB) from each station's ``[M, nx, ny]`` path gains, power and loading."""
    received_mw = gains * np.array([10.0 ** (bs.power_dbm / 10.0) for bs in stations])[:, None, None]
    loading = np.array([bs.loading for bs in stations])
    return best_server_sinr_db(received_mw, loading, 10.0 ** (params.noise_dbm / 10.0))


def ray_traced_radio_map(
    scene: str | os.PathLike[str] = "munich",
    *,
    altitude_m: float = 100.0,
    cell_m: float = 10.0,
    base_stations: Sequence[BaseStation] | None = None,
    extent: Extent | tuple[float, float, float, float] | None = None,
    params: RayTracingParams = RayTracingParams(),
    name: str | None = None,
) -> RadioMap:
    """The ray-traced expected-SINR map of ``scene`` at ``altitude_m`` on ``cell_m`` cells (module docstring).

    ``base_stations`` are in the map's frame (world (0, 0) = the first cell's centre); None places them on a
    grid (:func:`grid_base_stations`). ``extent`` is the measurement area in scene coordinates, by default the
    scene's bounding box. The map's :func:`provenance` says how it was made.
    """
    given = _checked_request(altitude_m, extent, cell_m)
    started = time.perf_counter()
    loaded = load_scene(scene)
    load_s = time.perf_counter() - started
    area = scene_extent(loaded) if given is None else given
    grid = MapGrid.covering(area, cell_m)
    stations = (
        grid_base_stations(loaded, grid, params)
        if base_stations is None
        else base_station_tuple(base_stations, "pass at least one BaseStation, or None to place them on a grid")
    )
    started = time.perf_counter()
    gains = path_gains(loaded, stations, grid, altitude_m, params)
    compute_s = time.perf_counter() - started
    sinr = _sinr_of_gains(gains, stations, params)
    scene_label = scene if isinstance(scene, str) and not scene.endswith(".xml") else str(Path(scene).resolve())
    record = {
        "format": NPZ_FORMAT,
        "generator": "uamfleet.radio.raytrace.ray_traced_radio_map",
        "scene": scene_label,
        "scene_origin_m": list(grid.scene_origin_m),
        "extent_m": dataclasses.astuple(area),
        "altitude_m": float(altitude_m),
        "cell_m": grid.cell_m,
        "gbs_placement": "given" if base_stations is not None else "grid",
        "params": dataclasses.asdict(params),
        "noise_dbm": params.noise_dbm,
        "sionna_rt_version": sionna_version(),
        "seed": params.seed,
        "scene_load_s": round(load_s, 3),
        "compute_s": round(compute_s, 3),
    }
    label = name if name is not None else Path(scene_label).stem if scene_label.endswith(".xml") else scene_label
    return RadioMap(
        sinr_db=sinr,
        resolution_m=grid.cell_m,
        name=label,
        altitude_m=float(altitude_m),
        base_stations=stations,
        source=_source_line(record) + " provenance: " + json.dumps(record, sort_keys=True),
    )


def _source_line(record: dict[str, Any]) -> str:
    p = record["params"]
    return (
        f"RAY-TRACED: Sionna RT {record['sionna_rt_version']}, scene {record['scene']}, "
        f"{p['carrier_ghz']:g} GHz, {p['antenna_pattern']} antenna tilted {p['downtilt_deg']:g} deg, "
        f"{p['samples_per_tx']} rays per GBS, max depth {p['max_depth']}, seed {record['seed']}."
    )


def provenance(radio: RadioMap) -> dict[str, Any]:
    """The provenance record of a ray-traced map (scene, frame, parameters, Sionna version, seed, timings)."""
    _, marker, tail = radio.source.partition(" provenance: ")
    if not marker:
        raise ValueError(f"radio map {radio.label!r} has no ray-tracing provenance (it was not made by raytrace)")
    record: dict[str, Any] = json.loads(tail)
    return record


# -- files ----------------------------------------------------------------------------------------------------------


def save_radio_map_npz(radio: RadioMap, path: str | os.PathLike[str]) -> Path:
    """Write ``radio`` (any map) as a ``.npz`` that :func:`read_radio_map_npz` reads back exactly, atomically."""
    path = Path(path)
    if path.suffix != ".npz":
        raise ValueError(f"radio map file {str(path)!r} must end in .npz (e.g. munich.npz)")
    stations = radio.base_stations
    buffer = io.BytesIO()
    np.savez_compressed(
        buffer,
        format=np.array(NPZ_FORMAT),
        sinr_db=radio.sinr_db,
        resolution_m=np.array(radio.resolution_m),
        origin_m=np.array(radio.origin_m),
        side_m=np.array(radio.side_m),
        altitude_m=np.array(radio.altitude_m),
        name=np.array(radio.name),
        is_estimate=np.array(radio.is_estimate),
        source=np.array(radio.source),
        bs_values=np.array([[getattr(bs, f) for f in _BS_FIELDS] for bs in stations]).reshape(-1, len(_BS_FIELDS)),
        bs_name=np.array([bs.name for bs in stations], dtype=str),
    )
    return write_bytes_atomic(path, buffer.getvalue())


def _npz_arrays(path: Path) -> dict[str, tuple[tuple[int, ...], np.dtype]]:
    """``{name: (shape, dtype)}`` of every array of the ``.npz`` at ``path``, from each member's ``.npy`` header
    alone (nothing of an array's data is read)."""
    arrays: dict[str, tuple[tuple[int, ...], np.dtype]] = {}
    with zipfile.ZipFile(path) as archive:
        for info in archive.infolist():
            if not info.filename.endswith(".npy"):
                continue
            with archive.open(info) as member:
                version = np.lib.format.read_magic(member)
                if version == (1, 0):
                    shape, _, dtype = np.lib.format.read_array_header_1_0(member)
                elif version == (2, 0):
                    shape, _, dtype = np.lib.format.read_array_header_2_0(member)
                else:
                    raise ValueError(f"its array {info.filename!r} has .npy format {version}; expected 1.0 or 2.0")
            arrays[info.filename.removesuffix(".npy")] = (tuple(int(n) for n in shape), dtype)
    return arrays


def read_radio_map_npz(path: str | os.PathLike[str]) -> RadioMap:
    """A map written by :func:`save_radio_map_npz` (``uamfleet-radio-map``); needs no Sionna.

    Every array's size is read from its header first: a raster or any other array over the size limits
    (:func:`~uamfleet.radio.radio_map.check_map_size`, docs/inputs.md "Size limits of maps") is refused with
    the size it would need before anything of it is read."""
    label = f"radio map {str(path)!r}"
    try:
        declared = _npz_arrays(Path(path))
        archive = np.load(Path(path), allow_pickle=False)
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as err:  # not an archive numpy can read
        raise ValueError(f"cannot read radio map {str(path)!r}: {err}") from err
    if not isinstance(archive, np.lib.npyio.NpzFile) or "format" not in archive.files:
        raise ValueError(f"{str(path)!r} is not a uamfleet radio map ({NPZ_FORMAT}); write one with uamfleet-radio-map")
    with archive as z:
        for name, (shape, dtype) in sorted(declared.items(), key=lambda item: item[0] == "sinr_db"):
            # every array in units of a float64 raster cell, the raster last (its cells are checked below)
            units = math.prod(shape) * dtype.itemsize / 8
            if name != "sinr_db" or dtype.itemsize > 8:
                check_size("map_cells", units, f"{label} (its array {name!r}: {shape} of {dtype})", 8)
        if str(z["format"]) != NPZ_FORMAT:
            raise ValueError(f"{str(path)!r} is a {z['format']} file; this uamfleet reads {NPZ_FORMAT} maps")
        try:
            shape = declared["sinr_db"][0]
            check_size("map_cells", math.prod(shape), f"{label} (a {' x '.join(map(str, shape))} raster)", 8)
            resolution_m, side_m = float(z["resolution_m"]), float(z["side_m"])
            origin = z["origin_m"]
            origin_m = (float(origin[0]), float(origin[1]))
            if len(shape) == 2 and all(map(math.isfinite, (resolution_m, side_m, *origin_m))) and resolution_m > 0:
                check_map_size(label, shape, resolution_m, side_m, origin_m)  # before the raster is read
            stations = tuple(
                BaseStation(**dict(zip(_BS_FIELDS, row, strict=True)), name=str(n))
                for row, n in zip(z["bs_values"].tolist(), z["bs_name"].tolist(), strict=True)
            )
            return RadioMap(
                sinr_db=z["sinr_db"],
                resolution_m=resolution_m,
                origin_m=origin_m,
                side_m=side_m,
                name=str(z["name"]),
                is_estimate=bool(z["is_estimate"]),
                altitude_m=float(z["altitude_m"]),
                base_stations=stations,
                source=str(z["source"]),
            )
        except KeyError as err:
            raise ValueError(
                f"radio map {str(path)!r} lacks the field {err}; write it again with uamfleet-radio-map"
            ) from err
