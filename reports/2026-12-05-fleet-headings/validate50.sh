#!/usr/bin/env bash
# The chosen dispatcher with heading=RULE (table or onward; default table) on validation episodes 0-49 of each
# issue-42 setting, as reports/2026-12-05-fleet-departures/validate50.sh flies a method (Berlin 4x48 and Detroit
# 4x24 in one process, Berlin 8x96 in another); rows in $OUT_DIR/<RULE>_<setting>.csv.
# usage: OUT_DIR=/tmp/val bash reports/2026-12-05-fleet-headings/validate50.sh [RULE]
set -euo pipefail
here=$(dirname "$0")
rule=${1:-table}
name="batch_assignment_value:value_price_s=100,wait=1,release=true,unassigned_price_s=1000,unassigned_guard_s=600,heading=$rule"
OUT_DIR=${OUT_DIR:-/tmp/val} bash "$here/../2026-12-05-fleet-departures/validate50.sh" "$rule" "$name"
