#!/usr/bin/env bash
# Label departures (label.py) on training episodes; runA.sh and runB.sh ran side by side (README.md).
mkdir -p /tmp/dep
cd "$(dirname "$0")/../.."  # the repository root; the .npz files go to /tmp/dep
export OMP_NUM_THREADS=1 OMP_WAIT_POLICY=PASSIVE PYTHONPATH=$PWD
P=${PYTHON:-.venv/bin/python}; L=reports/2026-12-05-fleet-departures/label.py
$P $L --family detroit3gpp --setting 4x24 --first 500000 --count 12 --max-wall-s 1000 --out /tmp/dep/d4x24.npz
$P $L --family berlin --setting 4x48 --first 600000 --count 10 --max-wall-s 1300 --out /tmp/dep/b4x48_b.npz
