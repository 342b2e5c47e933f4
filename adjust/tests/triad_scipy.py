"""A second opinion on gravcal's triad calibration: the same model, a = T K (X - B) in
imu_tk's body frame with |a| = g at every static position, solved by
scipy.optimize.least_squares on the static means. Prints the parameters and their sds as
JSON. Written for adjust/tests/triad.rs; independent of gravcal's code."""
import json
import sys

import numpy as np
from scipy.optimize import least_squares

d = np.loadtxt(sys.argv[1], delimiter=",", skiprows=1)
X, S, g = d[:, 0:3], d[:, 3:6], d[:, 6]


def vectors(p, x):
    a_yz, a_zy, a_zx = p[0:3]
    T = np.array([[1.0, -a_yz, a_zy], [0.0, 1.0, -a_zx], [0.0, 0.0, 1.0]])
    K = np.diag(p[3:6])
    return (T @ K @ (x - p[6:9]).T).T, T, K


def residuals(p):
    a, T, K = vectors(p, X)
    n = np.linalg.norm(a, axis=1)
    # sd of |a| from the means' sds: d|a|/dX = (a/|a|)^T T K.
    grad = (a / n[:, None]) @ T @ K
    sd = np.sqrt(np.sum((grad * S) ** 2, axis=1))
    return (n - g) / sd


# Start: T = I, each bias halfway between the axis's extremes, its scale from the spread.
lo, hi = X.min(axis=0), X.max(axis=0)
p0 = np.concatenate([np.zeros(3), 2 * g.mean() / (hi - lo), 0.5 * (lo + hi)])
fit = least_squares(residuals, p0, x_scale="jac", xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=2000)
J = fit.jac
cov = np.linalg.inv(J.T @ J)
print(json.dumps({"values": fit.x.tolist(), "sigmas": np.sqrt(np.diag(cov)).tolist(),
                  "status": int(fit.status), "cost": float(fit.cost)}))
