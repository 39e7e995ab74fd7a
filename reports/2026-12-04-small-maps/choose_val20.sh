#!/bin/bash
# The choice, on the training maps' validation (first 20 instances, seeds 1,000,000 ... 1,000,019): the shipped
# berlin and the mixture policy, each greedy as before and with idle_wait, beside replan.
set -e
R=reports/2026-12-04-small-maps
for map in berlin munich munich_3km; do
  python -m uamfleet bench --map $map --split validation --count 20 --jobs 1 \
      --methods replan learned:idle_wait=true --checkpoint uamfleet/data/pretrained/berlin.pt \
      --out-csv $R/choice_${map}_val20_berlin.csv --overwrite
  python -m uamfleet bench --map $map --split validation --count 20 --jobs 1 \
      --methods learned:idle_wait=true --checkpoint reports/2026-12-04-map-mixture/mixmaps.pt \
      --out-csv $R/choice_${map}_val20_mixmaps.csv --overwrite
done
