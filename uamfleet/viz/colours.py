"""Colours shared by the matplotlib figures, the legend and the 3-D scene (one palette for every view)."""

from __future__ import annotations

import numpy as np

TAXI_HEX = ("#d62728", "#1f77b4", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#17becf")
"""Taxi colours (matplotlib's tab10 order), shared by the matplotlib figures and the 3D viewer."""

NO_FLY_RGB = np.array([0.50, 0.04, 0.07])
NO_FLY_STRIPE_RGB = np.array([0.96, 0.62, 0.62])
NOT_COMPUTED_RGB = np.array([0.08, 0.08, 0.08])
PASSENGER_HEX = 0xFFFFFF
SERVED_HEX = 0x9E9E9E
POD_HEX = 0xFFD600
TOWER_HEX = 0x37474F
ANTENNA_HEX = 0xE53935
