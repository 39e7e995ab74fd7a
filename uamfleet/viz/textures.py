"""Pictures the 3-D scene shows: the radio map as a texture, text labels and the legend (PNG bytes).

Drawn with matplotlib and Pillow, imported when a picture is made; nothing here needs meshcat.
"""

from __future__ import annotations

import functools
import io
import math
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from uamfleet.radio import RadioMap
from uamfleet.viz.colours import (
    NO_FLY_RGB,
    NO_FLY_STRIPE_RGB,
    NOT_COMPUTED_RGB,
    POD_HEX,
    SERVED_HEX,
    TAXI_HEX,
    TOWER_HEX,
)

MAX_TEXTURE_CELLS = 1024
"""Raster cells per side drawn one texel each; larger rasters are reduced by an integer stride."""


def _png(rgba: np.ndarray) -> bytes:
    from PIL import Image

    buffer = io.BytesIO()
    Image.fromarray(rgba).save(buffer, format="PNG", optimize=True)
    return buffer.getvalue()


def colour_range(radio: RadioMap) -> tuple[float, float]:
    finite = radio.sinr_db[np.isfinite(radio.sinr_db)]
    if finite.size == 0:
        return -10.0, 10.0
    lo, hi = math.floor(float(finite.min())), math.ceil(float(finite.max()))
    return (lo, hi) if hi > lo else (lo - 1.0, hi + 1.0)


def map_texture(radio: RadioMap, threshold_db: float) -> tuple[bytes, int, tuple[float, float, float, float]]:
    """PNG of the SINR raster as drawn on ``radio_map`` (north up), the stride it was reduced by, and the extent
    it covers ``(x0, x1, y0, y1)`` in metres (cell edges)."""
    import matplotlib

    sinr = np.asarray(radio.sinr_db, dtype=np.float64)
    nx, ny = sinr.shape
    stride = max(1, math.ceil(max(nx, ny) / MAX_TEXTURE_CELLS))
    mx, my = math.ceil(nx / stride), math.ceil(ny / stride)
    padded = np.full((mx * stride, my * stride), np.nan)
    padded[:nx, :ny] = sinr
    blocks = padded.reshape(mx, stride, my, stride)
    with np.errstate(invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN blocks: NaN is the answer
        value = np.nanmean(blocks, axis=(1, 3))  # [mx, my]
        no_fly = ~(np.nan_to_num(blocks, nan=-np.inf) >= threshold_db).all(axis=(1, 3))
    lo, hi = colour_range(radio)
    rgb = matplotlib.colormaps["viridis"](np.clip((np.nan_to_num(value, nan=lo) - lo) / (hi - lo), 0, 1))[..., :3]
    rgb[no_fly] = 0.3 * rgb[no_fly] + 0.7 * NO_FLY_RGB
    rgb[np.isnan(value)] = NOT_COMPUTED_RGB
    # Upsample (nearest) so that no-fly cells can carry stripes, up to ~1400 texels a side.
    up = max(1, min(4, 1400 // max(mx, my)))
    img = np.repeat(np.repeat(rgb, up, axis=0), up, axis=1)  # [mx*up, my*up, 3] indexed [x, y]
    flag = np.repeat(np.repeat(no_fly & ~np.isnan(value), up, axis=0), up, axis=1)
    if up > 1:
        px, py = np.meshgrid(np.arange(img.shape[0]), np.arange(img.shape[1]), indexing="ij")
        stripe = flag & ((px + py) % (3 * up) < max(1, up // 2))
        img[stripe] = 0.45 * img[stripe] + 0.55 * NO_FLY_STRIPE_RGB
    rows_north_up = (np.clip(img, 0, 1) * 255).round().astype(np.uint8).transpose(1, 0, 2)[::-1]
    res, (ox, oy) = radio.resolution_m, radio.origin_m
    x0, y0 = ox - res / 2, oy - res / 2
    extent = (x0, x0 + mx * stride * res, y0, y0 + my * stride * res)
    return _png(np.ascontiguousarray(rows_north_up)), stride, extent


@functools.cache
def _font(size_px: int) -> Any:
    import matplotlib
    from PIL import ImageFont

    path = Path(matplotlib.get_data_path()) / "fonts" / "ttf" / "DejaVuSans-Bold.ttf"
    return ImageFont.truetype(str(path), size_px)


def label_png(text: str, fg: str = "#ffffff", bg: str = "#000000c8", size_px: int = 44) -> tuple[bytes, float]:
    """A text label as an RGBA PNG (rounded box) and its width / height ratio."""
    from PIL import Image, ImageDraw

    font = _font(size_px)
    left, top, right, bottom = font.getbbox(text)
    pad = size_px // 3
    w, h = right - left + 2 * pad, size_px + 2 * pad
    img = Image.new("RGBA", (w, h), (0, 0, 0, 0))
    draw = ImageDraw.Draw(img)
    draw.rounded_rectangle((0, 0, w - 1, h - 1), radius=pad, fill=bg)
    draw.text((pad - left, pad + (size_px - (bottom - top)) / 2 - top), text, font=font, fill=fg)
    buffer = io.BytesIO()
    img.save(buffer, format="PNG")
    return buffer.getvalue(), w / h


def grid_spacing_m(radio: RadioMap) -> float:
    return 500.0 if (radio.side_m or 0.0) <= 5000.0 else 1000.0


def _title_lines(title: str, width: int = 34) -> list[str]:
    """Break a title at its " · " separators (then at spaces) into lines of about ``width`` characters."""
    import textwrap

    lines: list[str] = []
    for part in title.split(" · "):
        if lines and len(lines[-1]) + 3 + len(part) <= width:
            lines[-1] += " · " + part
        else:
            lines += textwrap.wrap(part, width) or [""]
    return lines


def _legend_entries(no_fly_hex: str, base_stations: bool, num_taxis: int) -> list[tuple[str, str, str]]:
    """(marker, face colour, text) of each legend row: "s" a square swatch, else a matplotlib marker."""
    entries = [("s", no_fly_hex, "below γ_T: no-fly (striped)"), ("s", "#141414", "not computed (N.C.)")]
    if base_stations:
        entries.append(("o", "#ffffff", "GBS: ring on map, mast below"))
    entries += [
        ("v", "#ffffff", "S#: pick-up"),
        ("s", "#ffffff", "D#: drop-off"),
        ("s", f"#{SERVED_HEX:06x}", "served"),
    ]
    entries.append(("o", f"#{POD_HEX:06x}", "pod: passenger on board"))
    entries += [("s", TAXI_HEX[a % len(TAXI_HEX)], f"taxi {a}: path, start disc") for a in range(min(num_taxis, 8))]
    return entries


def _colour_bar(cax: Any, radio: RadioMap, threshold_db: float, no_fly_hex: str) -> None:
    """The SINR colour bar with the no-fly range shaded and the threshold marked in red."""
    import matplotlib
    from matplotlib.patches import Rectangle

    lo, hi = colour_range(radio)
    ramp = np.linspace(lo, hi, 256)[:, None]
    cax.imshow(ramp, origin="lower", aspect="auto", extent=(0, 1, lo, hi), cmap=matplotlib.colormaps["viridis"])
    if lo < threshold_db:
        cax.add_patch(Rectangle((0, lo), 1, min(threshold_db, hi) - lo, color=no_fly_hex, alpha=0.85, lw=0))
    cax.axhline(threshold_db, color="red", lw=2.5)
    cax.set_xticks([])
    cax.set_ylim(lo, hi)
    cax.tick_params(labelsize=8)
    cax.set_ylabel(f"SINR at {radio.altitude_m:g} m [dB]", fontsize=8.5)
    cax.annotate(f"γ_T = {threshold_db:g} dB", (1.0, threshold_db), xytext=(6, 0), textcoords="offset points",
                 fontsize=9, color="red", va="center", weight="bold", annotation_clip=False)  # fmt: skip


def legend_png(
    radio: RadioMap, threshold_db: float, title: str, num_taxis: int, z_scale: float, stride: int
) -> tuple[bytes, float]:
    """The legend drawn with matplotlib (title, colour bar with the threshold, symbols, taxi colours) as a PNG,
    and its width / height ratio."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.patches import Rectangle

    no_fly_hex = "#" + "".join(f"{round(c * 255):02x}" for c in NO_FLY_RGB)
    entries = _legend_entries(no_fly_hex, bool(radio.base_stations), num_taxis)
    grid = f"{grid_spacing_m(radio):g} m" if grid_spacing_m(radio) < 1000 else f"{grid_spacing_m(radio) / 1000:g} km"
    notes = f"heights ×{z_scale:.2g}, ground grid {grid}" + (f", raster 1/{stride}" if stride > 1 else "")
    lines = _title_lines(title)
    width, row, bar = 2.6, 0.2, 1.9  # inches
    top = 0.12 + 0.19 * len(lines) + 0.15
    height = top + bar + 0.2 + row * len(entries) + 0.3
    fig = Figure(figsize=(width, height), dpi=160)
    fig.patch.set_facecolor((1, 1, 1, 0.92))
    canvas = FigureCanvasAgg(fig)
    ax = fig.add_axes((0, 0, 1, 1))  # the whole legend in inches from the top-left corner
    ax.set_xlim(0, width)
    ax.set_ylim(height, 0)
    ax.set_axis_off()
    ax.text(0.12, 0.1, "\n".join(lines), fontsize=9, weight="bold", va="top")
    cax = fig.add_axes((0.55 / width, 1 - (top + bar) / height, 0.22 / width, bar / height))
    _colour_bar(cax, radio, threshold_db, no_fly_hex)
    y = top + bar + 0.3
    for marker, colour, text in entries:
        if marker == "s":
            ax.add_patch(Rectangle((0.12, y - 0.07), 0.2, 0.14, facecolor=colour, edgecolor="k", lw=0.6))
        else:
            ax.plot(0.22, y, marker=marker, ms=9, mfc=colour, mec="k", mew=0.8)
            if text.startswith("GBS"):
                ax.plot(0.22, y, marker="o", ms=4, color=f"#{TOWER_HEX:06x}")
        ax.text(0.42, y, text, fontsize=8.5, va="center")
        y += row
    ax.text(0.12, y + 0.06, notes, fontsize=7.5, va="center", color="0.3")
    buffer = io.BytesIO()
    canvas.print_png(buffer)
    return buffer.getvalue(), width / height
