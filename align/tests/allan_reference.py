"""allantools' overlapping Allan deviation of a series, for align/tests/allan.rs.

usage: python allan_reference.py FILE RATE_HZ M1,M2,...
FILE holds one value a line (frequency data). Prints CSV: m, tau_s, adev, edf, lo, hi
(the 68.3 % interval from allantools' edf_simple for white frequency noise).
"""
import sys

import allantools
import numpy as np

y = np.loadtxt(sys.argv[1])
rate = float(sys.argv[2])
ms = [int(m) for m in sys.argv[3].split(",")]
taus = np.array(ms) / rate
t, dev, _, _ = allantools.oadev(y, rate=rate, data_type="freq", taus=taus)
n_phase = len(y) + 1
print("m,tau_s,adev,edf,lo,hi")
for tau, d in zip(t, dev):
    m = int(round(tau * rate))
    edf = allantools.edf_simple(n_phase, m, 0)
    lo, hi = allantools.confidence_interval(d, edf, ci=0.683)
    print(f"{m},{tau!r},{d!r},{edf!r},{lo!r},{hi!r}")
