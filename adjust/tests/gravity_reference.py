"""Reference values for adjust/tests/gravity_peers.rs, from the peers the gravity stage is
checked against.

usage: python gravity_reference.py normal          prints lat,h,boule_mgal on a grid
       python gravity_reference.py filter IN FS PERIOD   prints scipy's sosfiltfilt of IN
       python gravity_reference.py firwin WINDOW TAPS CUTOFF P   prints scipy's firwin
                                                   (cycles per sample) a tap a line,
                                                   then |H| at 1 / P by freqz
       python gravity_reference.py gaussian M STD P   the same of scipy's gaussian window
                                                   of M points, its sum 1
       python gravity_reference.py shipgrav-nav SHIP IN  prints shipgrav's read_nav of IN:
                                                   unix seconds, lat, lon a fix a line
       python gravity_reference.py shipgrav-serial METER SHIP IN   prints shipgrav's
                                                   read_bgm_raw (METER bgm3) or read_dgs_raw
                                                   (dgs-raw) of IN: unix seconds (nan where
                                                   shipgrav finds no time), the reading (counts,
                                                   AD units), ve, vcc, al, ax (nan for a BGM-3)
       python gravity_reference.py eotvos IN FS    prints shipgrav's eotvos_full (mGal)
                                                   of IN's lon,lat,ht rows
       python gravity_reference.py shipgrav-track  prints lon,lat of shipgrav's own test
                                                   data (1 Hz), and its eotvos_full
       python gravity_reference.py shipgrav-ccp IN  prints shipgrav's cross-coupling fit
                                                   of IN, and the series it was given
       python gravity_reference.py shipgrav-faa IN  prints shipgrav's free-air anomaly of
                                                   the DGS laptop file IN (WGS84, Longman's
                                                   tide, unfiltered), wgs_grav and the
                                                   tide's correction, a line each
"""
import glob
import os
import sys

import numpy as np

what = sys.argv[1]
if what == "normal":
    import boule

    for lat in np.arange(-90.0, 90.01, 7.5):
        for h in [0.0, 10.0, 100.0, 1000.0, 3000.0, 10000.0]:
            gamma = boule.GRS80.normal_gravity((None, lat, h))
            print(f"{lat!r},{h!r},{float(gamma)!r}")
elif what == "filter":
    from scipy import signal

    x = np.loadtxt(sys.argv[2])
    fs, period = float(sys.argv[3]), float(sys.argv[4])
    sos = signal.butter(4, 1.0 / period, fs=fs, output="sos")
    for v in signal.sosfiltfilt(sos, x):
        print(repr(v))
elif what in ("firwin", "gaussian"):
    from scipy import signal

    if what == "firwin":
        h = signal.firwin(int(sys.argv[3]), float(sys.argv[4]), window=sys.argv[2], fs=1.0)
    else:
        h = signal.windows.gaussian(int(sys.argv[2]), float(sys.argv[3]))
        h = h / h.sum()
    for v in h:
        print(repr(v))
    _, resp = signal.freqz(h, worN=[2 * np.pi / float(sys.argv[-1])])
    print(repr(abs(resp[0])))
elif what == "shipgrav-nav":
    import shipgrav.io as sgi

    nav = sgi.read_nav(sys.argv[2], sys.argv[3], progressbar=False)
    for t, la, lo in zip(nav["time_sec"], nav["lat"], nav["lon"]):
        print(f"{t!r},{la!r},{lo!r}")
elif what == "shipgrav-serial":
    import shipgrav.io as sgi

    import contextlib

    meter, ship, path = sys.argv[2], sys.argv[3], sys.argv[4]
    # shipgrav says what it could not read on stdout: kept apart from the numbers.
    with contextlib.redirect_stdout(sys.stderr):
        if meter == "bgm3":
            d = sgi.read_bgm_raw(path, ship, progressbar=False)
        else:
            d = sgi.read_dgs_raw(path, ship, progressbar=False)
    if meter == "bgm3":
        reading, monitors = d["counts"], None
    else:
        reading = d["rgrav"] if "rgrav" in d else d["Gravity"]
        monitors = [d[m] for m in ("ve", "vcc", "al", "ax")]
    if "date_time" in d:
        t = [v.timestamp() for v in d["date_time"]]
    else:
        t = [float("nan")] * len(d)
    for k in range(len(d)):
        m = [float("nan")] * 4 if monitors is None else [float(c.iloc[k]) for c in monitors]
        print(",".join(repr(float(v)) for v in [t[k], reading.iloc[k]] + m))
elif what == "eotvos":
    import shipgrav.grav as sgg

    d = np.loadtxt(sys.argv[2], delimiter=",")
    for v in sgg.eotvos_full(d[:, 0], d[:, 1], d[:, 2], float(sys.argv[3])):
        print(repr(v))
elif what == "shipgrav-track":
    import shipgrav.grav as sgg
    import shipgrav.io as sgi

    files = glob.glob(os.path.dirname(sgg.__file__) + "/tests/ex_files/DGStest*.dat")
    data = sgi.read_dgs_laptop(files, "DGStest")
    lon, lat = data["lon"].values, data["lat"].values
    e = sgg.eotvos_full(lon, lat, np.zeros(len(lat)), 1)
    for a, b, c in zip(lon, lat, e):
        print(f"{a!r},{b!r},{c!r}")
elif what in ("shipgrav-faa", "shipgrav-ccp"):
    # shipgrav's free-air anomaly of the DGS laptop file, as shipgrav's own tests form it
    # (tests/test_grav_data.py): the meter's offset, WGS84 normal gravity with the
    # second-order free-air term (0 at height 0), Eotvos, Longman's tide.
    import shipgrav.grav as sgg
    import shipgrav.io as sgi

    data = sgi.read_dgs_laptop([sys.argv[2]], "DGStest", progressbar=False)
    grav = data["rgrav"].values + 969143
    lat, lon = data["lat"], data["lon"]
    normal = (sgg.wgs_grav(lat) + sgg.free_air_second_order(lat, np.zeros(len(lat)))).values
    e = sgg.eotvos_full(lon.values, lat.values, np.zeros(len(lat)), 1)
    lt = np.asarray(sgg.longman_tide_prediction(lon, lat, data["date_time"]))
    faa = grav - normal + e + lt
    if what == "shipgrav-faa":
        for f, n, t in zip(faa, normal, lt):
            print(f"{f!r},{n!r},{t!r}")
    else:
        # Its cross-coupling fit, as its tests call it: the first line the coefficients
        # (const, ve, vcc, al, ax), the second their OLS sds, then the anomaly and the four
        # monitors it was given, a line per sample.
        _, model = sgg.calc_cross_coupling_coefficients(
            faa, data["vcc"].values, data["ve"].values, data["al"].values, data["ax"].values,
            np.zeros(len(faa)))
        names = ["const", "ve", "vcc", "al", "ax"]
        print(",".join(repr(float(model.params[n])) for n in names))
        print(",".join(repr(float(model.bse[n])) for n in names))
        for row in zip(faa, data["ve"], data["vcc"], data["al"], data["ax"]):
            print(",".join(repr(float(v)) for v in row))
