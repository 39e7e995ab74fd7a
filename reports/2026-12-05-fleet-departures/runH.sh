#!/usr/bin/env bash
# The Berlin 4x48 episodes of runA.sh/runB.sh labelled again by label.py once it recorded the 10/30/100-step
# differences (the episode differences came out identical); side by side (README.md).
mkdir -p /tmp/dep2
cd "$(dirname "$0")/../.."  # the repository root
export OMP_NUM_THREADS=1 OMP_WAIT_POLICY=PASSIVE PYTHONPATH=$PWD
P=${PYTHON:-.venv/bin/python}; L=reports/2026-12-05-fleet-departures/label.py
$P $L --family berlin --setting 4x48 --first 500000 --count 13 --max-wall-s 1250 --out /tmp/dep2/h_a.npz &
$P $L --family berlin --setting 4x48 --first 600000 --count 10 --max-wall-s 1250 --out /tmp/dep2/h_b.npz
wait
