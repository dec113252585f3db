"""The short build-and-hold well and two-section string the drilling export and plot tests share: vertical to
100 m, 20 degrees at 250 m, a collar under drill pipe, the bit at 290 and 300 m."""

import numpy as np

from rodcont.drilling import Section

STATIONS = np.array([[0.0, 0, 0], [100.0, 0, 0], [250.0, 20.0, 30.0], [300.0, 20.0, 30.0]])
COLLAR = Section("collar", 50.0, 1.71e7, 1.32e7, 5.88e9, 2189.0, 0.0889)
PIPE = Section("pipe", None, 1.23e6, 9.5e5, 7.05e8, 285.0, 0.0635)
HOLE = 0.2159
DEPTHS = (290.0, 300.0)
