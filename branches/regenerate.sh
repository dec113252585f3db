#!/usr/bin/env bash
# Regenerate the regression family (paper values, N = 30 moving breakpoints, k = 5) and its response diagram.
set -euo pipefail
cd "$(dirname "$0")"
for g in 0 0.5 1 2 5 10; do
  rodcont trace --gamma "$g" --N 30 --adapt --out "gamma_$g.h5" --quiet > "/dev/null" &
done
wait
rodcont plot gamma_*.h5 -o response_diagram.png --title "Twisted heavy clamped rod (paper values, N = 30 adaptive, k = 5)"
