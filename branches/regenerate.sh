#!/usr/bin/env bash
# Regenerate the regression data: the whole response diagram (every branch, every fold up to Phi = 40)
# for each Gamma of the paper's Figure 2, paper values, adaptive mesh from N = 15, k = 5; the solution
# is kept at every 20th point and at every special point (the table keeps every point). Then the figure.
set -euo pipefail
cd "$(dirname "$0")"
rm -f gamma_*.h5
rodcont sweep --gamma 0 0.5 1 2 5 10 --diagram --phi-max 40 --store-every 20 --out . --overwrite --quiet
rodcont plot diagram_0.h5 diagram_0.5.h5 diagram_1.h5 diagram_2.h5 diagram_5.h5 diagram_10.h5 \
    -o response_diagram.png --overwrite --title "Twisted heavy clamped rod: every branch up to Phi = 40 (paper values)"
rodcont plot diagram_0.h5 diagram_1.h5 diagram_5.h5 --x phi_L --y torque -o distinguished_diagram.png --overwrite \
    --title "Distinguished diagram: torque against Phi (Gamma = 0, 1, 5)"
# the README's rod in a pipe: Gamma = 1 in the straight example conduit (clearance 0.01), Phi from 0 to 20
rodcont trace --gamma 1 --conduit ../examples/conduit_straight.toml --phi-max 20 --out /tmp/rodcont_pipe.h5 \
    --overwrite --quiet
rodcont shape /tmp/rodcont_pipe.h5 --point 0 --point -1 -o pipe_shape.png --overwrite
