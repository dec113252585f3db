"""Drivers: each runs the generic solvers on the rod for one job (solve, trace, fold curve, diagram, sweep)."""
