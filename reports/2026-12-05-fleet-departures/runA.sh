#!/usr/bin/env bash
# Label departures (label.py) on training episodes; runA.sh and runB.sh ran side by side (README.md).
mkdir -p /tmp/dep
cd "$(dirname "$0")/../.."  # the repository root; the .npz files go to /tmp/dep
export OMP_NUM_THREADS=1 OMP_WAIT_POLICY=PASSIVE PYTHONPATH=$PWD
P=${PYTHON:-.venv/bin/python}; L=reports/2026-12-05-fleet-departures/label.py
$P $L --family berlin --setting 4x48 --first 500000 --count 13 --max-wall-s 1700 --out /tmp/dep/b4x48_a.npz
$P $L --family berlin --setting 8x48 --first 520000 --count 3 --points 25 --max-wall-s 700 --out /tmp/dep/b8x48.npz
