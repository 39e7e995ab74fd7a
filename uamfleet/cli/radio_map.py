"""Ray-trace the SINR map of a city with Sionna RT and write it for uamfleet (needs the extra: setup.sh --rt).

    uamfleet-radio-map --scene munich --altitude-m 100 --cell-m 10 --out munich.npz
    uamfleet-radio-map --scene my_city.xml --gbs-m 200 300 25 900 650 30 --out my_city.npz

``--scene``: a built-in Sionna scene (munich, etoile, florence, san_francisco, simple_street_canyon, ..., or
``empty``: free space) or a Mitsuba XML file (OpenStreetMap -> Blender -> Mitsuba export), checked before it is
loaded (docs/inputs.md, "Scenes": what a scene may contain, its size limits). Writes the map
(``.npz``: raster, GBS, provenance with scene, parameters, sionna-rt version and seed) and a preview
``<out stem>.png`` beside it, atomically; fly it with ``uamfleet.make_config("berlin_random", radio="munich.npz")``.
The map's frame: world (0, 0) is the centre of the first cell (min x, min y of ``--extent-m``, by default the
scene's bounding box), axes along the scene's x (east) and y (north); ``--gbs-m`` take that frame. Without
``--gbs-m`` the GBS are placed on a grid (``--gbs-spacing-m``; uamfleet/radio/raytrace.py says the rule).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, Literal

import numpy as np
import tyro

from uamfleet.cli._common import UsageError, check_outputs, output_path, run
from uamfleet.radio.radio_map import BaseStation, RadioMap
from uamfleet.radio.raytrace import (
    ANTENNA_PATTERNS,
    DEFAULT_CARRIER_GHZ,
    DEFAULT_GBS_HEIGHT_M,
    DEFAULT_GBS_SPACING_M,
    DEFAULT_MAX_DEPTH,
    DEFAULT_POWER_DBM,
    DEFAULT_SAMPLES_PER_TX,
    RayTracingParams,
    RayTracingUnavailableError,
    provenance,
    ray_traced_radio_map,
    save_radio_map_npz,
)
from uamfleet.radio.channel_3gpp import DEFAULT_BANDWIDTH_MHZ, DEFAULT_NOISE_FIGURE_DB
from uamfleet.viz.figures import _draw_sinr, _new_figure, save_figure

if TYPE_CHECKING:
    AntennaPattern = str
else:
    AntennaPattern = Literal[ANTENNA_PATTERNS]


def default_is(what: str) -> Any:
    """An option whose unset value (None or empty) means ``what``, said so in --help instead of "None"."""
    return tyro.conf.arg(help_behavior_hint=f"(default: {what})")


@dataclass
class Args:
    scene: str = "munich"
    """a built-in Sionna scene's name, or the path to a Mitsuba XML scene"""
    out: Path = Path("radio_map.npz")
    """the map to write (.npz); the preview goes to <stem>.png beside it"""
    altitude_m: float = 100.0
    """flight altitude: the height of the measurement plane [m]"""
    cell_m: float = 10.0
    """side of a raster cell [m]"""
    extent_m: Annotated[tuple[float, float, float, float] | None, default_is("the scene's bounding box")] = None
    """measurement area X0 Y0 X1 Y1 in scene metres"""
    gbs_m: Annotated[tuple[float, ...], default_is("a grid, see --gbs-spacing-m")] = ()
    """GBS as X Y HEIGHT triples in the map's frame [m]"""
    gbs_spacing_m: float = DEFAULT_GBS_SPACING_M
    """spacing of the automatic GBS grid [m] (750: Berlin's GBS density)"""
    gbs_height_m: float = DEFAULT_GBS_HEIGHT_M
    """height of the automatic GBS [m] (a roof + 3 m mast where a building is taller)"""
    carrier_ghz: float = DEFAULT_CARRIER_GHZ
    power_dbm: float = DEFAULT_POWER_DBM
    """transmit power of every GBS [dBm]"""
    antenna_pattern: AntennaPattern = "iso"
    """GBS antenna element (iso: no antenna gain, as TR 36.777's UMi-AV model; tr38901: 3GPP sector)"""
    downtilt_deg: float = 0.0
    azimuth_deg: float = 0.0
    """boresight of a directional antenna, counter-clockwise from east [deg]"""
    noise_figure_db: float = DEFAULT_NOISE_FIGURE_DB
    bandwidth_mhz: float = DEFAULT_BANDWIDTH_MHZ
    samples_per_tx: int = DEFAULT_SAMPLES_PER_TX
    """rays per GBS (Monte-Carlo: more is smoother and slower)"""
    max_depth: int = DEFAULT_MAX_DEPTH
    """reflections/refractions per ray"""
    seed: int = 42
    """the ray tracer's sampling seed"""
    threads: Annotated[int | None, default_is("all cores")] = None
    """CPU threads of the ray tracer"""
    threshold_db: float = -3.0
    """SINR below which the preview greys a cell (Berlin's threshold)"""
    overwrite: bool = False
    """replace an existing --out and its preview: else the command refuses before any work"""


def preview_path(out: Path) -> Path:
    return out.with_suffix(".png")


def base_stations(args: Args) -> tuple[BaseStation, ...] | None:
    """``--gbs-m`` as base stations, or None (place them on a grid)."""
    if not args.gbs_m:
        return None
    if len(args.gbs_m) % 3:
        raise UsageError(f"--gbs-m takes X Y HEIGHT triples; got {len(args.gbs_m)} numbers: {args.gbs_m}")
    triples = np.asarray(args.gbs_m, dtype=float).reshape(-1, 3)
    return tuple(
        BaseStation(x_m=x, y_m=y, height_m=h, power_dbm=args.power_dbm, frequency_mhz=args.carrier_ghz * 1e3,
                    name=f"GBS {k}")
        for k, (x, y, h) in enumerate(triples.tolist())
    )  # fmt: skip


def write_preview(radio: RadioMap, threshold_db: float, path: Path) -> None:
    """The SINR raster (cells below ``threshold_db`` greyed) with the GBS as red triangles."""
    fig = _new_figure(7.0, 6.0)
    ax = fig.add_axes((0.1, 0.1, 0.72, 0.8))
    image = _draw_sinr(ax, radio, threshold_db)
    fig.colorbar(image, cax=fig.add_axes((0.85, 0.1, 0.03, 0.8)), label=f"SINR [dB] (grey: < {threshold_db:g} dB)")
    for bs in radio.base_stations:
        ax.plot(bs.x_m, bs.y_m, marker="^", ms=9, color="red", mec="k", ls="none")
    ax.set_xlabel("x [m] (east)")
    ax.set_ylabel("y [m] (north)")
    ax.set_title(f"{radio.name}: ray-traced SINR at {radio.altitude_m:g} m, {len(radio.base_stations)} GBS")
    save_figure(fig, path)


def main(args: Args) -> RadioMap:
    if args.out.suffix != ".npz":
        raise UsageError(f"--out {args.out}: the map is written as .npz; give a name such as munich.npz")
    output_path(args.out, "--out")
    check_outputs(args.overwrite, [args.out, preview_path(args.out)])
    if args.threads is not None and args.threads < 1:
        raise UsageError(f"--threads {args.threads}: give at least 1 thread (or leave it out for all cores)")
    params = RayTracingParams(
        carrier_ghz=args.carrier_ghz, power_dbm=args.power_dbm, gbs_height_m=args.gbs_height_m,
        gbs_spacing_m=args.gbs_spacing_m, antenna_pattern=args.antenna_pattern, downtilt_deg=args.downtilt_deg,
        azimuth_deg=args.azimuth_deg, noise_figure_db=args.noise_figure_db, bandwidth_mhz=args.bandwidth_mhz,
        samples_per_tx=args.samples_per_tx, max_depth=args.max_depth, seed=args.seed,
    )  # fmt: skip
    stations = base_stations(args)
    try:
        if args.threads is not None:
            import drjit

            drjit.set_thread_count(args.threads)
        radio = ray_traced_radio_map(
            args.scene, altitude_m=args.altitude_m, cell_m=args.cell_m, base_stations=stations,
            extent=args.extent_m, params=params,
        )  # fmt: skip
    except (RayTracingUnavailableError, ImportError) as err:
        raise UsageError(str(err)) from None
    save_radio_map_npz(radio, args.out)
    write_preview(radio, args.threshold_db, preview_path(args.out))
    record = provenance(radio)
    finite = radio.sinr_db[np.isfinite(radio.sinr_db)]
    print(
        f"{radio.name}: {radio.shape[0]} x {radio.shape[1]} cells of {radio.resolution_m:g} m at "
        f"{radio.altitude_m:g} m, "
        f"{len(radio.base_stations)} GBS; scene loaded in {record['scene_load_s']:.1f} s, map in "
        f"{record['compute_s']:.1f} s; SINR median {np.median(finite):.1f} dB, 5-95 % "
        f"{np.percentile(finite, 5):.1f} ... {np.percentile(finite, 95):.1f} dB; "
        f"{np.mean(finite < args.threshold_db) * 100:.1f} % of cells below {args.threshold_db:g} dB"
    )
    for path in (args.out, preview_path(args.out)):
        print(f"wrote {path} ({path.stat().st_size / 1e3:.0f} kB)")
    return radio


def cli(argv: Sequence[str] | None = None, prog: str = "uamfleet-radio-map") -> int:
    """The ``uamfleet-radio-map`` command."""
    return run(main, Args, argv, prog, __doc__)


if __name__ == "__main__":
    raise SystemExit(cli(prog="python -m uamfleet.cli.radio_map"))
