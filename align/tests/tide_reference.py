"""Reference values of the body tide for align/tests/tide.rs: ETERNA (through PyGTide) and
an independent Longman implementation (tidegravity), at a site over a span of time.

usage: python tide_reference.py LAT LON HEIGHT_M START_DATE HOURS STEP_S
prints CSV: utc (YYYY-MM-DDTHH:MM:SS), eterna_mgal, longman_mgal; both as the tide's effect
on gravity (positive when gravity is larger than tide-free).
"""
import sys

import numpy as np
import pandas as pd
from pygtide import pygtide
from tidegravity import solve_longman_tide

lat, lon, height = (float(x) for x in sys.argv[1:4])
start, hours, step = sys.argv[4], int(sys.argv[5]), int(sys.argv[6])
pt = pygtide(msg=False)
# PyGTide's default wave group (0-10 cycles/day) has amplitude factor 1: a rigid Earth.
# gravcal uses the elastic Earth's gravimetric factor 1 + h2 - 3/2 k2 = 1.1575 for all waves.
pt.set_wavegroup(np.array([[0.0, 10.0, 1.1575, 0.0]]))
# tidalcompo 0: the vertical component of the gravity tide, nm/s^2.
pt.predict(lat, lon, height, start, hours, step, tidalcompo=0)
d = pt.results()
eterna = d["Tide [nm/s**2]"].to_numpy() / 1e4
times = pd.DatetimeIndex(d["UTC"].dt.tz_localize(None))
n = len(times)
_, _, up = solve_longman_tide(
    np.full(n, lat), np.full(n, lon), np.full(n, height), times
)
longman = -np.asarray(up)  # tidegravity gives the upward tidal acceleration
print("utc,eterna_mgal,longman_mgal")
for t, e, l in zip(times, eterna, longman):
    print(f"{t:%Y-%m-%dT%H:%M:%S},{e:.9f},{l:.12f}")
