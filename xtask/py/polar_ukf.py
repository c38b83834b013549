"""The filterpy UKF over the paper's polar model that `cargo xtask compare` and
`cargo xtask dukf-table` run as a peer (in target/py-venv; never from cargo test).

One `UnscentedKalmanFilter` over the state augmented with the leader's velocities
`[x1, y1, theta1, l12, alpha12, beta12, v1, w1]`: the model `PolarModel::f` (spec 2.4, RK4 over
dt with the follower's inputs held, angles wrapped), mirrored here, the velocities a random
walk; `h` the formation variables; Merwe sigma points; angle-aware means and residuals.
"""

import math

import numpy as np
from filterpy.kalman import MerweScaledSigmaPoints, UnscentedKalmanFilter


def wrap(a):
    return (a + math.pi) % (2 * math.pi) - math.pi if not (-math.pi < a <= math.pi) else a


STATE_ANGLES = (2, 4, 5)


def derivative(x, v2, w2, d):
    """PolarModel::derivative (spec 2.4) with the leader's velocities from the state."""
    _, _, th1, l, a, b, v1, w1 = x
    sa, ca = math.sin(a), math.cos(a)
    sb, cb = math.sin(b), math.cos(b)
    common = (-v1 * sa + v2 * sb) / l
    return np.array([v1 * math.cos(th1), v1 * math.sin(th1), w1,
                     v1 * ca - v2 * cb - d * w2 * sb,
                     common - w1 - d * w2 * cb / l,
                     common - w2 * (1.0 + d * cb / l), 0.0, 0.0])


def fx(x, dt, u=(0.0, 0.0), d=0.5):
    """PolarModel::f: one RK4 step with inputs held, angles wrapped; v1, w1 a random walk."""
    v2, w2 = u
    k1 = derivative(x, v2, w2, d)
    k2 = derivative(x + 0.5 * dt * k1, v2, w2, d)
    k3 = derivative(x + 0.5 * dt * k2, v2, w2, d)
    k4 = derivative(x + dt * k3, v2, w2, d)
    nxt = x + (k1 + 2 * k2 + 2 * k3 + k4) * (dt / 6.0)
    for i in STATE_ANGLES:
        nxt[i] = wrap(nxt[i])
    return nxt


def hx(x):
    return np.array([x[3], x[4], x[5]])


def residual_x(a, b):
    y = a - b
    for i in STATE_ANGLES:
        y[i] = wrap(y[i])
    return y


def residual_z(a, b):
    y = a - b
    y[1] = wrap(y[1])
    y[2] = wrap(y[2])
    return y


def circular_mean(sigmas, wm, angles):
    x = np.dot(wm, sigmas)
    for i in angles:
        x[i] = math.atan2(np.dot(wm, np.sin(sigmas[:, i])), np.dot(wm, np.cos(sigmas[:, i])))
    return x



def run(run):
    """Filters one exported run: `dt`, `d`, `ut` (alpha, beta, kappa), `x0` (6), `w0` (2),
    `p0` (6) and `pw0` (2) diagonals, `q` (6) and `rr` (2) per-step process noise diagonals,
    `r` (3), `measurements` (one [l12, alpha12, beta12] per step) and `inputs` (the
    follower's [v2, w2] over the step before each). Returns one [l12, alpha12, beta12, v1,
    w1] estimate per step."""
    dt, d = run["dt"], run["d"]
    alpha, beta, kappa = run["ut"]
    points = MerweScaledSigmaPoints(8, alpha=alpha, beta=beta, kappa=kappa,
                                    subtract=residual_x)
    ukf = UnscentedKalmanFilter(
        dim_x=8, dim_z=3, dt=dt, hx=hx, fx=fx, points=points,
        x_mean_fn=lambda s, w: circular_mean(s, w, STATE_ANGLES),
        z_mean_fn=lambda s, w: circular_mean(s, w, (1, 2)),
        residual_x=residual_x, residual_z=residual_z)
    ukf.x = np.array(run["x0"] + run["w0"], dtype=np.float64)
    ukf.P = np.diag(run["p0"] + run["pw0"])
    ukf.Q = np.diag(run["q"] + run["rr"])
    ukf.R = np.diag(run["r"])
    est = []
    for z, u in zip(run["measurements"], run["inputs"]):
        ukf.predict(u=tuple(u), d=d)
        ukf.update(np.array(z))
        x = ukf.x
        est.append([float(x[3]), float(x[4]), float(x[5]), float(x[6]), float(x[7])])
    return est
