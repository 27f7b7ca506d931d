"""Write the notebooks in this folder from the cell lists below.

The committed ``.ipynb`` files are what users open and what the test suite
runs; this script is a convenience for editing them as plain text. Run
``python notebooks/_generate.py`` from the repository root after editing a
cell list, then commit the regenerated notebooks (they carry no outputs).
Notebooks edited directly in Jupyter are fine too: clear their outputs
before committing (``tests/test_notebooks.py`` checks that).
"""

import sys
from pathlib import Path

import nbformat

HERE = Path(__file__).resolve().parent

# ----------------------------------------------------------------------
# 1. Quick start
# ----------------------------------------------------------------------
QUICKSTART = [
    ("md", r"""# 1. Quick start: recursive least squares step by step

This notebook follows the lecture notes (Lesson 11, *Recursive least-squares*) literally:

1. initialize $P_{k_0}$ and $\hat\theta_{k_0}$ with a small batch least squares;
2. sample a new data point $y[k]$, $u[k]$;
3. form the regressor $\phi_k$;
4. update $P_k$ with formula (1);
5. update $\hat\theta_k$ with formula (2);
6. repeat with the remaining data.

We write the algorithm once in plain NumPy, check that it reproduces batch least squares at every
step, and then run the same thing with `rlsfilt.RecursiveLeastSquares`."""),
    ("code", r"""import numpy as np
import matplotlib.pyplot as plt
from scipy.signal import lfilter

from rlsfilt import RecursiveLeastSquares

plt.rcParams.update({"figure.dpi": 150, "savefig.dpi": 150})   # sharp figures
rng = np.random.default_rng(11)"""),
    ("md", r"""## A simulated plant in the notes' form

The notes' ARX model of order $n$ has a direct term $b_0 u[k]$:

$$\hat y[k] = -a_1 y[k-1] - \dots - a_n y[k-n] + b_0 u[k] + \dots + b_n u[k-n].$$

We take $n = 2$ with $a = (-1.5, 0.7)$ and $b = (0.2, 1.0, 0.5)$, drive it with a random binary
input and add white equation noise of standard deviation 0.5. (In MATLAB's `[na nb nk]` convention this is
`na = 2, nb = 3, nk = 0`.)"""),
    ("code", r"""a_true = np.array([-1.5, 0.7])          # a1, a2
b_true = np.array([0.2, 1.0, 0.5])      # b0, b1, b2
theta_true = np.r_[a_true, b_true]
n, N = 2, 600

u = np.where(rng.random(N) < 0.5, -1.0, 1.0)
e = 0.5 * rng.standard_normal(N)
y = lfilter(b_true, np.r_[1.0, a_true], u) + lfilter([1.0], np.r_[1.0, a_true], e)

# regressor rows phi_k = [-y[k-1], -y[k-2], u[k], u[k-1], u[k-2]] for k = n .. N-1
Phi = np.column_stack([-y[1:-1], -y[:-2], u[2:], u[1:-1], u[:-2]])
Y = y[n:]
d = Phi.shape[1]
print(f"{len(Y)} complete rows, d = 2n + 1 = {d} parameters")"""),
    ("md", r"""## Step 1: a small batch least squares

The batch start needs at least $d = 2n+1$ independent rows (the notes' $l \ge 3n$). We use
$k_0 = 10$ rows and solve through a QR factorization $\Phi_{k_0} = Q_1 R_1$ rather than by
inverting $\Phi^\top\Phi$, which would square the condition number:
$\hat\theta_{k_0} = R_1^{-1} Q_1^\top Y_{k_0}$ and $P_{k_0} = (\Phi_{k_0}^\top\Phi_{k_0})^{-1} = R_1^{-1}R_1^{-\top}$."""),
    ("code", r"""k0 = 10
Q1, R1 = np.linalg.qr(Phi[:k0])
theta = np.linalg.solve(R1, Q1.T @ Y[:k0])
R1inv = np.linalg.inv(R1)
P = R1inv @ R1inv.T
print("theta after the batch start:", np.round(theta, 3))"""),
    ("md", r"""## Steps 2-6: formulas (1) and (2)

With a regressor **row** $\phi_k$ the covariance update (1) needs no matrix inverse, only the scalar
$1 + \phi_k P_{k-1} \phi_k^\top$:

$$P_k = P_{k-1} - \frac{P_{k-1}\phi_k^\top \phi_k P_{k-1}}{1 + \phi_k P_{k-1} \phi_k^\top} \quad (1)
\qquad
\hat\theta_k = \hat\theta_{k-1} + P_k \phi_k^\top \big(y[k] - \phi_k\hat\theta_{k-1}\big) \quad (2)$$"""),
    ("code", r"""history = np.empty((len(Y), d))
history[:k0] = np.nan
history[k0 - 1] = theta
for k in range(k0, len(Y)):
    phi = Phi[k]                         # step 3: the new regressor row
    g = P @ phi                          # P_{k-1} phi^T
    P = P - np.outer(g, g) / (1.0 + phi @ g)     # step 4: formula (1)
    residual = Y[k] - phi @ theta        # a-priori residual
    theta = theta + P @ phi * residual   # step 5: formula (2)
    history[k] = theta

print("true      :", theta_true)
print("recursive :", np.round(theta, 4))"""),
    ("md", r"""## It is batch least squares, at every step

Because each step is an exact rearrangement of the batch solution, the recursive estimate after
sample $k$ equals least squares on rows $0..k$. We check it at every step against
`numpy.linalg.lstsq`."""),
    ("code", r"""gap = max(
    np.max(np.abs(history[k] - np.linalg.lstsq(Phi[:k + 1], Y[:k + 1], rcond=None)[0]))
    for k in range(k0, len(Y))
)
print(f"largest |recursive - batch| over all steps: {gap:.1e}")
assert gap < 1e-9"""),
    ("code", r"""fig, ax = plt.subplots(figsize=(8, 4))
names = ["a1", "a2", "b0", "b1", "b2"]
k = np.arange(len(Y)) + n
for i, name in enumerate(names):
    line, = ax.plot(k, history[:, i], label=name)
    ax.axhline(theta_true[i], color=line.get_color(), ls=":", lw=1)
ax.set(xlabel="sample k", ylabel=r"$\hat\theta_k$", xscale="log",
       title="Recursive estimates after the batch start (dotted: true)")
ax.legend(ncol=5, loc="lower right")
ax.set_ylim(-2.2, 1.6);"""),
    ("md", r"""## The same with `RecursiveLeastSquares`

`RecursiveLeastSquares` has the API of filterpy's `KalmanFilter`. `initialize` is step 1 (a QR batch
start), `predict` is the time update (it only matters with forgetting or a random walk) and
`update(z, H)` is formulas (1) and (2) with the regressor row as the measurement matrix `H`."""),
    ("code", r"""rls = RecursiveLeastSquares(dim_x=d)
rls.initialize(Y[:k0], Phi[:k0])
for z, phi in zip(Y[k0:], Phi[k0:]):
    rls.predict()
    rls.update(z, H=phi)

print(rls.x.ravel())
np.testing.assert_allclose(rls.x.ravel(), theta, rtol=1e-10, atol=1e-12)
np.testing.assert_allclose(rls.x.ravel(), np.linalg.lstsq(Phi, Y, rcond=None)[0], rtol=1e-9)"""),
    ("md", r"""`batch_filter` runs the whole record at once and returns every intermediate estimate and
covariance (time on axis 0). With $R$ set to the noise variance, `P` is the covariance of the
estimate, so the standard errors come straight from its diagonal."""),
    ("code", r"""sigma2 = np.mean((Y - Phi @ rls.x.ravel()) ** 2) * len(Y) / (len(Y) - d)
rls = RecursiveLeastSquares(dim_x=d, R=sigma2)
rls.initialize(Y[:k0], Phi[:k0])
means, covs, _, _ = rls.batch_filter(Y[k0:], Phi[k0:])
std = np.sqrt(np.diagonal(covs, axis1=1, axis2=2))

for name, est, s, t in zip(names, means[-1, :, 0], std[-1], theta_true):
    print(f"{name}: {est:8.4f} +- {s:.4f}   (true {t:5.2f})")
assert np.all(np.abs(means[-1, :, 0] - theta_true) < 4 * std[-1])"""),
    ("code", r"""fig, ax = plt.subplots(figsize=(8, 3.5))
kk = np.arange(k0, len(Y)) + n
for i, name in enumerate(names[2:], start=2):
    ax.plot(kk, means[:, i, 0], label=name)
    ax.fill_between(kk, means[:, i, 0] - 2 * std[:, i], means[:, i, 0] + 2 * std[:, i], alpha=0.2)
ax.set(xlabel="sample k", ylabel="estimate", xscale="log",
       title="b coefficients with 2-sigma bands")
ax.legend();"""),
    ("md", r"""## In one line: `ARX(...).fit`

`rlsfilt.ARX` builds the regressors itself from MATLAB's `[na nb nk]` orders. The notes' model of
order $n$ has the direct term $b_0 u[k]$, so it is `ARX(na=n, nb=n+1, nk=0)`, and the notes' $b_0$
is `ARX`'s $b_1$. `method="rls"` runs the same recursion as above (batch start on the first `k0`
rows, then formulas (1) and (2)), `method="ls"` solves the batch problem through QR."""),
    ("code", r"""from rlsfilt import ARX

model = ARX(na=2, nb=3, nk=0).fit(u, y, method="rls", k0=k0)
print(model.summary())

np.testing.assert_allclose(model.theta_, theta, rtol=1e-9)          # our loop above
np.testing.assert_allclose(model.theta_history_[k0:], history[k0:], rtol=1e-8, atol=1e-12)
batch = ARX(na=2, nb=3, nk=0).fit(u, y)                             # batch least squares
np.testing.assert_allclose(model.theta_, batch.theta_, rtol=1e-9)
print("a =", model.a_, " b =", model.b_)"""),
    ("md", r"""The fitted model converts to python-control for analysis and design (notebooks 3 and 4):"""),
    ("code", r"""G = model.to_tf()
print(G)
print("poles:", np.round(G.poles(), 4), "  true:", np.round(np.roots(np.r_[1.0, a_true]), 4))"""),
    ("md", r"""## Where next

- [Notebook 2](02_tracking.ipynb) tracks plants whose parameters change (forgetting, windup and
  its remedies).
- [Notebook 3](03_validation.ipynb) validates a model and selects its order against the true
  plant.
- [Notebook 4](04_control.ipynb) designs a controller on the identified model.
- [Notebook 5](05_beside_filterpy.ipynb) puts `RecursiveLeastSquares` beside filterpy's
  `KalmanFilter`.
- [Notebook 6](06_real_records.ipynb) takes a measured-like record through the whole workflow
  (operating point, delay, orders on fresh data, saved model)."""),
]

# ----------------------------------------------------------------------
# 5. Beside filterpy
# ----------------------------------------------------------------------
FILTERPY = [
    ("md", r"""# 5. rlsfilt beside filterpy

`RecursiveLeastSquares` is written to sit next to filterpy's `KalmanFilter`: the same method names
(`predict`, `update(z, H)`, `batch_filter`), the same state attributes (`x`, `P`, `K`, `y`, `S`),
the same `Saver`. This notebook shows that

1. one loop, written once, drives either filter;
2. filterpy's `Saver` records either filter;
3. RLS *is* a Kalman filter: with $F = I$ the two agree to round-off, for exponential
   forgetting (filterpy's fading memory) and for a random-walk `Q`."""),
    ("code", r"""import numpy as np
import matplotlib.pyplot as plt
from filterpy.common import Saver
from filterpy.kalman import KalmanFilter

from rlsfilt import RecursiveLeastSquares

plt.rcParams.update({"figure.dpi": 150, "savefig.dpi": 150})   # sharp figures
rng = np.random.default_rng(5)"""),
    ("md", r"""## A plant whose gain drifts

A first-order plant $y(t) = -a\,y(t-1) + b(t)\,u(t-1) + e(t)$ whose input gain $b$ changes from
1.0 to 0.6 halfway. The regressor row is $\phi(t) = [-y(t-1),\ u(t-1)]$ and the parameters
$\theta = [a, b]$."""),
    ("code", r"""N = 800
a = -0.9
b = np.where(np.arange(N) < N // 2, 1.0, 0.6)
u = np.where(rng.random(N) < 0.5, -1.0, 1.0)
y = np.zeros(N)
for t in range(1, N):
    y[t] = -a * y[t - 1] + b[t] * u[t - 1] + 0.05 * rng.standard_normal()

Hs = np.column_stack([-y[:-1], u[:-1]])    # (N-1, 2), time on axis 0
zs = y[1:]
theta_true = np.column_stack([np.full(N - 1, a), b[1:]])"""),
    ("md", r"""## One loop for both filters

The loop below is plain filterpy code. It runs unchanged on a `KalmanFilter` configured as a
parameter estimator ($F = I$) and on a `RecursiveLeastSquares`, and filterpy's `Saver` records
both."""),
    ("code", r"""def run(f, zs, Hs):
    saver = Saver(f)
    for z, h in zip(zs, Hs):
        f.predict()
        f.update(z, H=h.reshape(1, -1))
        saver.save()
    saver.to_array()
    return saver


lam = 0.98                                  # forgetting factor: memory ~ 1/(1 - lam) = 50 samples

kf = KalmanFilter(dim_x=2, dim_z=1)
kf.F = np.eye(2)                            # constant parameters ...
kf.Q = np.zeros((2, 2))
kf.R = 1.0
kf.P = 1e4 * np.eye(2)                      # ... broad prior, as MATLAB's rarx
kf.alpha = 1 / np.sqrt(lam)                 # fading memory: P <- alpha^2 P = P / lam

rls = RecursiveLeastSquares(dim_x=2, lam=lam, P0=1e4)

s_kf = run(kf, zs, Hs)
s_rls = run(rls, zs, Hs)
print(s_kf.x.shape, s_rls.x.shape)          # (N-1, 2, 1) for both
np.testing.assert_allclose(s_rls.x, s_kf.x, rtol=1e-8, atol=1e-10)
np.testing.assert_allclose(s_rls.P, s_kf.P, rtol=1e-8, atol=1e-12)
np.testing.assert_allclose(s_rls.K, s_kf.K, rtol=1e-8, atol=1e-12)
np.testing.assert_allclose(s_rls.y, s_kf.y, rtol=1e-8, atol=1e-10)
print("x, P, K and y agree at every step")"""),
    ("md", r"""The per-step log-likelihoods agree as well (both compute $\log\mathcal N(y; 0, S)$ lazily):"""),
    ("code", r"""np.testing.assert_allclose(s_rls.log_likelihood[1:], s_kf.log_likelihood[1:], rtol=1e-8)
print(f"total log-likelihood: {np.sum(s_rls.log_likelihood[1:]):.2f}")"""),
    ("md", r"""## The Kalman view: a random walk instead of forgetting

Forgetting divides $P$ by $\lambda$ at every step. The Kalman-filter alternative is to say how fast
the parameters move: $\theta_{t+1} = \theta_t + w_t$ with $w_t \sim \mathcal N(0, Q)$, so that the
time update is $P \leftarrow P + Q$. `RecursiveLeastSquares(Q=...)` and `KalmanFilter` with the same
`Q` are again the same filter; `batch_filter` has the same signature shape as filterpy's."""),
    ("code", r"""q = np.diag([1e-6, 2e-4])       # the gain b is allowed to move, the pole hardly

kf = KalmanFilter(dim_x=2, dim_z=1)
kf.F, kf.Q, kf.R, kf.P = np.eye(2), q, 0.05 ** 2, 1e4 * np.eye(2)
m_kf, c_kf, _, _ = kf.batch_filter(zs, Hs=[h.reshape(1, -1) for h in Hs])

rls_q = RecursiveLeastSquares(dim_x=2, Q=q, R=0.05 ** 2, P0=1e4)
m_rls, c_rls, _, _ = rls_q.batch_filter(zs, Hs)

np.testing.assert_allclose(m_rls, m_kf, rtol=1e-7, atol=1e-9)
np.testing.assert_allclose(c_rls, c_kf, rtol=1e-7, atol=1e-12)
print("batch_filter: random-walk RLS == KalmanFilter")"""),
    ("code", r"""fig, axes = plt.subplots(1, 2, figsize=(10, 3.5), sharey=True)
t = np.arange(1, N)
for ax, means, title in ((axes[0], s_rls.x, f"exponential forgetting, lam = {lam}"),
                         (axes[1], m_rls, "random walk Q (Kalman view)")):
    ax.plot(t, means[:, 0, 0], label="a estimate")
    ax.plot(t, means[:, 1, 0], label="b estimate")
    ax.plot(t, theta_true[:, 0], "k:", lw=1)
    ax.plot(t, theta_true[:, 1], "k:", lw=1, label="true")
    ax.set(xlabel="sample t", title=title)
axes[0].set(ylabel="parameter", ylim=(-1.2, 1.4))
axes[1].legend(loc="lower left");"""),
    ("md", r"""Both track the change in $b$. Forgetting forgets every direction equally; the random walk lets
each parameter move at its own rate, so the pole estimate stays quieter.

## What differs from filterpy

- `update(z, H)` validates `H` (one regressor row of length `dim_x`) and `z`; filterpy broadcasts
  silently when `H` is given. `batch_filter` refuses inputs of different lengths instead of
  truncating.
- `initialize(zs, Hs)` starts the filter from batch least squares (the lecture notes' step 1), after
  which every step equals batch least squares on all data so far.
- A missing measurement (`None` or NaN) keeps the estimate and sets `K` to zero and `y` to NaN.
- Several outputs share one regressor row (`dim_z > 1`) and one `P`."""),
]


# ----------------------------------------------------------------------
# 2. Tracking time-varying plants
# ----------------------------------------------------------------------
TRACKING = [
    ("md", r"""# 2. Tracking time-varying plants

Least squares on all data so far cannot follow a plant that changes: every old sample keeps its
full weight. This notebook

1. tracks a parameter jump with exponential forgetting and shows the memory/noise trade-off of the
   forgetting factor $\lambda$;
2. provokes **covariance windup** (the input stops exciting the plant, $P$ explodes) and compares
   the anti-windup schemes of `RecursiveLeastSquares(forgetting=...)` and a Kalman random walk;
3. replaces forgetting by an exact **sliding window** (`SlidingWindowRLS`)."""),
    ("code", r"""import warnings

import matplotlib.pyplot as plt
import numpy as np

from rlsfilt import ARX, RecursiveLeastSquares, SlidingWindowRLS
from rlsfilt.datasets import prbs, time_varying
from rlsfilt.plotting import plot_parameters, plot_trace, plot_tracking

plt.rcParams.update({"figure.dpi": 150, "savefig.dpi": 150})   # sharp figures"""),
    ("md", r"""## A parameter jump

`rlsfilt.datasets.time_varying` simulates the ARX(2, 2, 1) plant
$y(t) + a_1 y(t-1) + a_2 y(t-2) = b_1 u(t-1) + b_2 u(t-2) + e(t)$ whose parameters jump halfway
through the record. `ds.theta_true` holds the true parameters at every sample."""),
    ("code", r"""ds = time_varying(rng=0)
print(ds)
print("before:", ds.theta_true[0], " after:", ds.theta_true[-1])"""),
    ("code", r"""fig, axes = plt.subplots(1, 2, figsize=(11, 3.8), sharey=True)
for ax, lam in zip(axes, (1.0, 0.98)):
    model = ARX(*ds.orders).fit(ds.u, ds.y, method="rls", lam=lam)
    lag = model.max_lag
    plot_parameters(model, t=ds.t[lag:], true_values=ds.theta_true[lag:], ax=ax)
    ax.set_title(f"lam = {lam}")
axes[0].set_ylim(-2, 1.5);"""),
    ("md", r"""With $\lambda = 1$ (ordinary least squares) the estimate after the jump is a compromise between
the two plants and converges to the new one only as fast as the old data are outweighed. With
$\lambda = 0.98$ a sample $j$ steps old has weight $0.98^j$, a memory of about
$1/(1-\lambda) = 50$ samples, and the estimate follows the jump.

## The trade-off: memory against noise

A short memory tracks fast but averages little noise. We measure both: the settling time after the
jump (until every parameter is within 0.05 of the truth) and the RMS parameter error while the
plant is constant."""),
    ("code", r"""jump = ds.change_time
print(f"{'lam':>6} {'memory':>7} {'settling [samples]':>19} {'RMS error, constant plant':>26}")
for lam in (0.9, 0.95, 0.98, 0.99, 0.995):
    model = ARX(*ds.orders).fit(ds.u, ds.y, method="rls", lam=lam)
    lag = model.max_lag
    err = np.abs(model.theta_history_ - ds.theta_true[lag:])
    after = np.max(err[jump - lag:], axis=1)
    settle = int(np.argmax(np.convolve(after < 0.05, np.ones(20), "valid") == 20))
    rms = np.sqrt(np.nanmean(err[200:jump - lag] ** 2))
    print(f"{lam:6.3f} {1 / (1 - lam):7.0f} {settle:19d} {rms:26.4f}")"""),
    ("md", r"""### Try it: a forgetting-factor slider

`show(lam)` fits the model recursively with forgetting factor `lam` and draws the estimates over the
filter's one-step errors (`plot_tracking` of an `ARX` fitted with `method="rls"`). Here it is for
$\lambda = 0.95$; in a live Jupyter session with `ipywidgets` installed, the cell after it gives a
slider (the rendered documentation shows only this static figure)."""),
    ("code", r"""from IPython.display import display


def show(lam=0.98):
    model = ARX(*ds.orders, dt=ds.dt).fit(ds.u, ds.y, method="rls", lam=lam)
    lag = model.max_lag
    fig = plot_tracking(model, t=ds.t[lag:], true_values=ds.theta_true[lag:],
                        xlabel="time (s)")
    fig.axes[0].set_ylim(-2, 1.5)
    fig.suptitle(f"lam = {lam:.3f}: memory about {1 / (1 - lam):.0f} samples"
                 if lam < 1 else "lam = 1: no forgetting")
    display(fig)
    plt.close(fig)


show(0.95)"""),
    ("code", r"""try:
    import ipywidgets as widgets
except ImportError:  # no widgets: the static figure above is the whole story
    widgets = None
if widgets is not None:
    widgets.interact(show, lam=widgets.FloatSlider(
        value=0.98, min=0.90, max=1.0, step=0.005, readout_format=".3f",
        continuous_update=False, description="lam"))""", {"tags": ["remove-output"]}),
    ("md", r"""## Covariance windup

Exponential forgetting divides $P$ by $\lambda$ at every step, also in directions the data no longer
excite. We hold the input constant for 2000 samples (only one regressor direction stays excited),
then resume a rich input, and change the plant at that moment."""),
    ("code", r"""rng = np.random.default_rng(2)
N1, N2, N3 = 500, 2000, 700
u = np.r_[prbs(N1, rng=1), np.ones(N2), prbs(N3, rng=2)]
th_before, th_after = np.array([-1.5, 0.7, 1.0, 0.5]), np.array([-1.2, 0.5, 0.6, 0.9])
y = np.zeros(N1 + N2 + N3)
for t in range(2, len(y)):
    a1, a2, b1, b2 = th_before if t < N1 + N2 else th_after
    y[t] = -a1 * y[t - 1] - a2 * y[t - 2] + b1 * u[t - 1] + b2 * u[t - 2] \
        + 0.05 * rng.standard_normal()

Phi, z = ARX(2, 2, 1).regressors(u, y)          # rows phi(t) for t = 2 .. N-1
truth = np.array([th_before if t < N1 + N2 else th_after for t in range(2, len(y))])
k0 = 8                                          # batch start on the first 8 rows
t_axis = np.arange(2 + k0, len(y))"""),
    ("md", r"""Every filter gets `R` = the noise variance ($0.05^2$): then $P$ is the covariance of the estimate
in the units of the parameters, and the $\pm 2\sigma$ bands drawn below have the right width. (The
estimates of exponential, directional, constant-trace and EFRA forgetting do not depend on `R`;
variable forgetting uses it to judge which residuals are large.)"""),
    ("code", r"""R = 0.05 ** 2                                   # the noise variance
filters = {
    "exponential": RecursiveLeastSquares(4, lam=0.98, R=R),
    "directional": RecursiveLeastSquares(4, lam=0.98, R=R, forgetting="directional"),
    "constant_trace": RecursiveLeastSquares(4, lam=0.98, R=R, forgetting="constant_trace"),
    "efra": RecursiveLeastSquares(4, lam=0.98, R=R, forgetting="efra"),
    "variable": RecursiveLeastSquares(4, lam=0.98, R=R, forgetting="variable"),
    "random walk Q": RecursiveLeastSquares(4, Q=1e-4, R=R),
}
runs = {}
for name, f in filters.items():
    f.initialize(z[:k0], Phi[:k0])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        means, covs, _, _ = f.batch_filter(z[k0:], Phi[k0:])
    runs[name] = (means[:, :, 0], covs)
    if caught:
        print(f"{name}: {caught[0].category.__name__}: {str(caught[0].message)[:90]}...")"""),
    ("code", r"""change = N1 + N2 - 2 - k0                       # row index of the change
lo, hi = np.minimum(th_before, th_after), np.maximum(th_before, th_after)


def settling(err, tol=0.05, hold=20):
    ok = np.convolve(np.max(err, axis=1) < tol, np.ones(hold), "valid") == hold
    return int(np.argmax(ok)) if ok.any() else None


print(f"{'scheme':>15} {'max tr P (hold)':>16} {'overshoot':>10} {'settling':>9} "
      f"{'RMS error, last 400':>20}")
for name, (m, c) in runs.items():
    tr = np.trace(c, axis1=1, axis2=2)
    after = m[change:]
    overshoot = np.max(np.maximum(after[:100] - hi, lo - after[:100]).clip(min=0))
    err = np.abs(after - th_after)
    st = settling(err)
    print(f"{name:>15} {tr[:change].max():16.3g} {overshoot:10.3f} "
          f"{st if st is not None else '-':>9} {np.sqrt(np.mean(err[-400:] ** 2)):20.4f}")

assert np.trace(runs["exponential"][1][change - 1]) > 1e10      # windup
for name in ("directional", "constant_trace", "efra", "random walk Q"):
    assert np.trace(runs[name][1][:change], axis1=1, axis2=2).max() < 100"""),
    ("md", r"""During the hold, $\mathrm{tr}\,P$ under exponential forgetting grows by many orders of magnitude
(and `RecursiveLeastSquares` warns that $P$ became ill-conditioned). When excitation returns, the
huge gain throws the estimate far outside the range of the old and new parameters ("overshoot").
The anti-windup schemes keep $P$ bounded ("settling" counts the samples after the change until
every parameter stays within 0.05 of the new plant):

* **directional** forgetting forgets only in the excited direction (Kulhavý & Kárný 1984); it
  re-tracks slowly after the change, because it has "forgotten" little;
* **constant trace** rescales $P$ to a fixed trace (Goodwin & Sin 1984);
* **EFRA** (Salgado, Goodwin & Middleton 1988) bounds $P$ between two limits;
* **variable** forgetting (Fortescue et al. 1981) forgets only when the residuals are large
  compared with the noise level `R`, so it needs `R` to be the noise variance;
* a **random walk** $Q$ (the Kalman view) makes $P$ grow linearly, not exponentially; over a long
  hold that is still enough covariance to overshoot, so $Q$ has to match how fast the plant really
  drifts.

No scheme wins everywhere: directional forgetting barely moves while the plant is constant and for
the same reason re-tracks a sudden change slowly; constant trace settles late; EFRA and variable
forgetting overshoot a little but settle fast."""),
    ("code", r"""fig, axes = plt.subplots(2, 1, figsize=(10, 6.5), sharex=True, layout="constrained")
for name, (m, c) in runs.items():
    plot_trace((m, c), t=t_axis, label=name, ax=axes[1], xlabel="sample $t$")
    axes[0].plot(t_axis, m[:, 2], lw=1, label=name, color=axes[1].get_lines()[-1].get_color())
axes[0].plot(t_axis, truth[k0:, 2], "k:", label="true $b_1$")
axes[0].set(ylabel="$b_1$ estimate", ylim=(-1, 3), title="held input from t = 500 to 2500")
axes[0].legend(loc="upper left", bbox_to_anchor=(1.01, 1), frameon=False, fontsize="small")
for ax in axes:
    ax.axvspan(N1, N1 + N2, color="0.92", zorder=0)"""),
    ("md", r"""`rlsfilt.plotting.plot_tracking` draws the parameter trajectories with their $\pm 2\sigma$ bands
and $\mathrm{tr}\,P$ in one figure, here for EFRA:"""),
    ("code", r"""m, c = runs["efra"]
fig = plot_tracking((m, c), t=t_axis, names=["a1", "a2", "b1", "b2"], true_values=truth[k0:])
fig.set_size_inches(10, 6)"""),
    ("md", r"""## A sliding window

`SlidingWindowRLS` drops the oldest sample exactly (a downdate) instead of down-weighting it: its
estimate is ordinary least squares on the last `window` samples, and nothing before. We check that
against `numpy.linalg.lstsq` on the window, at the end of the jump record."""),
    ("code", r"""Phi_j, z_j = ARX(*ds.orders).regressors(ds.u, ds.y)
window = 100
sw = SlidingWindowRLS(4, window=window)
means_sw, _, _, _ = sw.batch_filter(z_j, Phi_j)

exact = np.linalg.lstsq(Phi_j[-window:], z_j[-window:], rcond=None)[0]
np.testing.assert_allclose(sw.x.ravel(), exact, rtol=1e-8, atol=1e-10)
print("sliding window:", np.round(sw.x.ravel(), 4))
print("lstsq, last 100:", np.round(exact, 4))"""),
    ("code", r"""ewls = RecursiveLeastSquares(4, lam=1 - 2 / window)      # about the same memory
ewls.initialize(z_j[:8], Phi_j[:8])
means_ew, _, _, _ = ewls.batch_filter(z_j[8:], Phi_j[8:])

fig, ax = plt.subplots(figsize=(10, 3.5))
lag = 2
ax.plot(ds.t[lag:], means_sw[:, 0, 0], label=f"sliding window, {window} samples")
ax.plot(ds.t[lag + 8:], means_ew[:, 0, 0], label=f"exponential, lam = {1 - 2 / window:g}")
ax.plot(ds.t, ds.theta_true[:, 0], "k:", label="true")
ax.set(xlabel="time [s]", ylabel="$a_1$ estimate", ylim=(-1.8, -1.0),
       xlim=(ds.change_time - 200, ds.change_time + 300))
ax.legend();"""),
    ("md", r"""After the jump the sliding window forgets the old plant completely once the window has passed
it (100 samples later); exponential forgetting of similar memory reacts sooner but never forgets
completely. Choose the window from how fast the plant can change, as you would choose $\lambda$."""),
]

# ----------------------------------------------------------------------
# 3. Validation and order selection
# ----------------------------------------------------------------------
VALIDATION = [
    ("md", r"""# 3. Validation and order selection against the true plant

A model is only as good as the tests it survives. With simulated data we can do what is never
possible on a real process: compare the identified model with the **true plant**. This notebook

1. chooses the ARX orders by an information criterion (`select_order`, MATLAB's
   `arxstruc`/`selstruc`);
2. validates the model on fresh data: fit, residual whiteness and independence, information
   criteria (`validate`, MATLAB's `compare` and `resid`);
3. compares it with the true plant through python-control: Bode, step response, poles and zeros;
4. shows what the residual tests catch: a too-simple model, coloured noise, a plant that changes."""),
    ("code", r"""import control
import matplotlib.pyplot as plt
import numpy as np

from rlsfilt import ARX, select_order, validate
from rlsfilt.datasets import nonminimum_phase, time_varying
from rlsfilt.plotting import plot_plant_comparison
from rlsfilt.validation import cusum, cusum_squares, frequency_response_band

plt.rcParams.update({"figure.dpi": 150, "savefig.dpi": 150})   # sharp figures"""),
    ("md", r"""## Estimation and validation data

The plant is a non-minimum-phase process, $G(s) = (1 - s/0.5)/((s+1)(0.5 s+1))$, sampled with a
zero-order hold at $dt = 0.2$ s: its step response first moves the wrong way. Two independent
experiments give estimation and validation records."""),
    ("code", r"""est = nonminimum_phase(rng=0)
val = nonminimum_phase(rng=1)
print(est)
print("true plant:", est.plant)"""),
    ("md", r"""## Order selection

Every combination of $n_a \in 1..4$, $n_b \in 1..4$, $n_k \in 0..3$ is fitted on the same rows and
scored by BIC. One QR factorization of the largest regressor matrix serves all 64 candidates."""),
    ("code", r"""sel = select_order(est.u, est.y, na=range(1, 5), nb=range(1, 5), nk=range(0, 4), dt=est.dt)
print(str(sel.summary())[:700])
assert sel.best == (est.na, est.nb, est.nk)"""),
    ("code", r"""sel.plot();"""),
    ("md", r"""BIC finds the true structure ARX(2, 2, 1). Larger models fit the estimation data a little better
(their loss is lower), but not by enough to pay for their extra parameters.

## Validation on fresh data"""),
    ("code", r"""model = ARX(*sel.best, dt=est.dt).fit(est.u, est.y)
print(model.summary())"""),
    ("code", r"""report = validate(model, val.u, val.y, plant=val.plant)
print(report.summary())
assert report.passed"""),
    ("code", r"""report.plot();"""),
    ("md", r"""## Against the true plant, with python-control

`model.to_tf()` is an ordinary python-control transfer function, so the usual tools apply. The
identified zero lies outside the unit circle, like the true one: the model has kept the
non-minimum-phase character that a controller design must respect."""),
    ("code", r"""G_true, G_model = est.plant, model.to_tf()
print("poles  true:", np.round(np.sort(G_true.poles().real), 4),
      " model:", np.round(np.sort(G_model.poles().real), 4))
print("zeros  true:", np.round(G_true.zeros().real, 4), " model:", np.round(G_model.zeros().real, 4))
print(f"DC gain true: {G_true.dcgain():.4f}  model: {G_model.dcgain():.4f}")
np.testing.assert_allclose(np.sort(G_model.poles().real), np.sort(G_true.poles().real), atol=0.01)
np.testing.assert_allclose(G_model.zeros().real, G_true.zeros().real, rtol=0.01)"""),
    ("md", r"""`report.plant_comparison` holds the comparison behind those numbers; with the model's 95 %
uncertainty band (`frequency_response_band`, parameter draws from the estimate's covariance) the
true plant lies inside the band over the whole frequency range:"""),
    ("code", r"""comparison = report.plant_comparison
band = frequency_response_band(model, omega=comparison.omega, rng=0)
print(f"plant inside the band at {band.contains(comparison.response_plant).mean():.0%} "
      "of the frequencies")
fig = plot_plant_comparison(comparison, band=band)"""),
    ("code", r"""fig, ax = plt.subplots(figsize=(4.5, 4.5))
theta = np.linspace(0, 2 * np.pi, 200)
ax.plot(np.cos(theta), np.sin(theta), "k", lw=0.5)
for G, name, mk in ((G_true, "true", "o"), (G_model, "model", "+")):
    ax.plot(G.poles().real, G.poles().imag, "x" if mk == "o" else "1", ms=10, label=f"{name} poles")
    ax.plot(G.zeros().real, G.zeros().imag, mk, mfc="none", ms=10, label=f"{name} zeros")
ax.set(aspect="equal", xlabel="Re z", ylabel="Im z", title="Poles and zeros")
ax.legend(fontsize="small");"""),
    ("md", r"""## What the tests catch

**A model that is too simple.** ARX(1, 1, 1) cannot describe a second-order plant: its residuals
are strongly correlated and its fit poor. An over-parameterized ARX(4, 4, 1) passes the tests but
BIC penalizes the extra parameters."""),
    ("code", r"""print(f"{'orders':>10} {'passed':>7} {'sim fit %':>10} {'Ljung-Box p':>12} {'BIC':>10} "
      f"{'freq. error':>12}")
for orders in [(1, 1, 1), (2, 2, 1), (4, 4, 1)]:
    m = ARX(*orders, dt=est.dt).fit(est.u, est.y)
    r = validate(m, val.u, val.y, plant=val.plant)
    print(f"{str(orders):>10} {str(r.passed):>7} {r.simulation_fit:10.2f} "
          f"{r.residuals[0].pvalue_white:12.3g} {r.criteria.bic:10.1f} "
          f"{r.plant_comparison.frequency_error:12.3%}")"""),
    ("md", r"""**Coloured noise.** Least squares on an ARX model is consistent only when the equation error is
white. With coloured noise (`noise="colored"`) the estimate is biased however much data there is,
and the residual test says so: the residuals inherit the colour."""),
    ("code", r"""coloured = nonminimum_phase(noise="colored", rng=0)
m = ARX(*coloured.orders, dt=coloured.dt).fit(coloured.u, coloured.y)
r = validate(m, coloured.u, coloured.y, plant=coloured.plant)
print("true     :", np.round(coloured.theta, 4))
print("estimate :", np.round(m.theta_, 4), "+-", np.round(m.std_errors_, 4))
print(f"bias in standard errors: {np.round((m.theta_ - coloured.theta) / m.std_errors_, 1)}")
print(f"whiteness p-value {r.residuals[0].pvalue_white:.2g} -> passed: {r.passed}")
assert not r.passed"""),
    ("md", r"""**A plant that changes.** The CUSUM tests of Brown, Durbin & Evans (1975) run on the recursive
residuals of RLS (the one-step errors of the notes' algorithm, normalized): if the parameters are
constant their cumulative sums stay within the lines (except in a fraction `alpha` = 5 % of
experiments: a false alarm); a parameter change drives them out."""),
    ("md", r"""The tests run on the rows of the regression `Phi, z = model.regressors(u, y)`; row `r` is
sample `r + max_lag` of the record. Passing the sample of each row as `t` puts the marks on the
record's own time axis."""),
    ("code", r"""fig, axes = plt.subplots(1, 2, figsize=(13, 3.8), layout="constrained")
for ax, ds, title in ((axes[0], val, "constant plant"),
                      (axes[1], time_varying(rng=0), "parameter jump at t = 1000")):
    Phi, z = ARX(*ds.orders).regressors(ds.u, ds.y)
    t = np.arange(len(ds.y) - len(z), len(ds.y))          # the sample of each row
    result = cusum_squares(z, Phi)
    result.plot(ax=ax, t=t)
    ax.set_title(f"{title}\n" + ax.get_title())
    line = (f"{title:28s} CUSUM rejected: {cusum(z, Phi).rejected}, "
            f"CUSUM of squares rejected: {result.rejected}")
    if result.rejected:
        m = len(result.index)                              # the diagonal (r - k) / m
        k = np.argmax(np.abs(result.statistic - np.arange(1, m + 1) / m))
        departure = t[result.index[k]]
        line += f" (largest departure at sample {departure})"
    print(line)"""),
    ("md", r"""After the jump the residuals are larger, so the normalized sum of squares $S_t$ grows slowly
at first and leaves the band early, long before the change (the thick stretch outside the lines);
the place where it departs furthest from the diagonal, sample 999, dates the change at t = 1000. A
test that does not reject gets no marks."""),
]

# ----------------------------------------------------------------------
# 4. From identification to a controller
# ----------------------------------------------------------------------
CONTROL = [
    ("md", r"""# 4. From identification to a controller

Identification is rarely the goal; control is. This notebook goes from data to a controller with
`rlsfilt.adaptive`:

1. identify a DC motor (voltage to speed) as an ARX model;
2. design a pole-placement controller with integral action on the **identified** model with
   `rst_design`;
3. simulate the closed loop against the **true** plant with python-control, with a load
   disturbance;
4. close an adaptive loop: a self-tuning regulator, identification and redesign at every sample,
   inside `control.interconnect`, on a motor whose gain changes five-fold, where the fixed
   controller goes unstable.

The guide page *From identification to control* is the reference for every function used here."""),
    ("code", r"""import control
import matplotlib.pyplot as plt
import numpy as np

from rlsfilt import ARX, RecursiveLeastSquares, validate
from rlsfilt.adaptive import SelfTuningRegulator, rst_design
from rlsfilt.datasets import dc_motor"""),
    ("md", r"""## 1. Identify the plant"""),
    ("code", r"""ds = dc_motor(rng=0)
model = ARX(*ds.orders, dt=ds.dt).fit(ds.u, ds.y)
report = validate(model, ds.u, ds.y, plant=ds.plant)
print(ds.description)
print(model.summary())
print(f"simulation fit {report.simulation_fit:.1f} %, residual tests passed: {report.passed}")
dt = ds.dt"""),
    ("md", r"""## 2. Pole placement with integral action

The two-degree-of-freedom controller $R(q^{-1})\,u(t) = T(q^{-1})\,r(t) - S(q^{-1})\,y(t)$ around
$A(q^{-1})\,y = B(q^{-1})\,u$ gives $y = \frac{B T}{A R + B S}\, r$ (Åström & Wittenmark,
*Computer-Controlled Systems*, ch. 5). `rst_design` solves the Diophantine equation
$A R + B S = A_m A_o$ through the Sylvester matrix, with

- $R = (1 - q^{-1}) R'$: an integrator, so constant disturbances and gain errors of the model
  leave no steady-state error;
- $A_m$ from a continuous-time prototype ($\omega_n = 8$ rad/s, $\zeta = 0.8$, poles
  $z = e^{s\,dt}$) and the observer polynomial $A_o$ with poles at 0.3 and 0.35;
- $T = t_0 A_o$, $t_0 = A_m(1)/B(1)$: the observer poles cancel from the reference, unit static
  gain.

Polynomials are arrays of coefficients of ascending powers of $q^{-1}$, as `model.polynomials()`
returns them; `np.poly(poles)` makes a monic polynomial with given zeros in the z-plane."""),
    ("code", r"""wn, zeta = 8.0, 0.8
Am = np.real(np.poly(np.exp(np.roots([1.0, 2 * zeta * wn, wn ** 2]) * dt)))
Ao = np.poly([0.3, 0.35])
ctrl = rst_design(model, Am=Am, Ao=Ao)          # = rst_design(*model.polynomials(), Am, Ao)
print(ctrl)
designed = ctrl.closed_loop(model)
print(designed)
np.testing.assert_allclose(np.sort_complex(designed.poles),
                           np.sort_complex(np.roots(np.convolve(Am, Ao))), rtol=0, atol=1e-9)"""),
    ("md", r"""## 3. The closed loop on the true plant, in python-control

`ctrl.to_ss()` is the controller as a python-control system with inputs `[r, y]` and output
`u`. Interconnected with the plant and a summing junction for a load disturbance $v$ at the
plant input, it gives the loop on the identified model (the design) and on the true plant. A
load step of -2 V at $t = 3$ s is rejected without offset: the integrator at work."""),
    ("code", r"""def closed_loop(G, ctrl):
    # the plant with a load disturbance v at its input, the RST controller around it
    plant = control.ss(G, inputs="w", outputs="y", name="plant")
    load = control.summing_junction(["u", "v"], "w", name="load")
    K = control.ss(ctrl.to_ss(), inputs=["r", "y"], outputs="u", name="rst")
    return control.interconnect([plant, load, K], inputs=["r", "v"], outputs=["y", "u"])


t = np.arange(120) * dt
r = np.ones_like(t)
v = np.where(t >= 3.0, -2.0, 0.0)
on_model = control.forced_response(closed_loop(model.to_tf(), ctrl), t, [r, v])
on_true = control.forced_response(closed_loop(ds.plant, ctrl), t, [r, v])
diff = np.max(np.abs(on_true.outputs[0] - on_model.outputs[0]))
print(f"largest difference of the responses on the model and on the true plant: {diff:.2e}")
print(f"output at the end on the true plant: {on_true.outputs[0, -1]:.6f}")
true_loop = ctrl.closed_loop(ds.true_model())
print("closed-loop poles on the true plant:", np.round(np.sort_complex(true_loop.poles), 4))
gm, pm, wcg, wcp = control.margin(ds.plant * -ctrl.to_tf()[0, 1])
print(f"loop on the true plant: gain margin {gm:.2f}, phase margin {pm:.1f} deg")
assert diff < 0.01 and abs(on_true.outputs[0, -1] - 1.0) < 1e-6 and true_loop.stable

fig, axes = plt.subplots(1, 2, figsize=(11, 3.5), layout="constrained")
axes[0].step(t, on_model.outputs[0], where="post", label="on the model (design)")
axes[0].step(t, on_true.outputs[0], "--", where="post", label="on the true plant")
axes[0].axvline(3.0, color="0.6", lw=0.8)
axes[0].set(xlabel="t [s]", ylabel="speed y", title="Reference step, load step at t = 3 s")
axes[0].legend()
axes[1].step(t, on_true.outputs[1], where="post")
axes[1].set(xlabel="t [s]", ylabel="voltage u", title="Control on the true plant");"""),
    ("md", r"""## 4. A self-tuning regulator on a plant that changes

At $t = 45$ s a load change multiplies the motor's gain by 5, more than the gain margin of the
fixed design (4.3) allows. A **self-tuning regulator** (Åström & Wittenmark, *Adaptive Control*,
ch. 3) closes the loop around the identification; at every sample it

1. updates the recursive least-squares estimate of $A, B$ with the regressor
   $\varphi(t) = [-y(t-1), -y(t-2), u(t-1), u(t-2)]$ (forgetting factor 0.98);
2. redesigns $R, S, T$ with `rst_design` and the same $A_m$, $A_o$ (keeping the last controller
   if the estimated $A$ and $B$ nearly share a factor), with the estimated $b_i$ kept
   non-negative by projection;
3. computes $u(t)$ from $R u = T r - S y$; a small binary dither keeps the loop exciting.

The estimator starts from the identified model and the regulator from the design above. The motor
with its gain change is a python-control `nlsys`; the regulator goes into `control.interconnect`
through `as_iosystem()`, and the fixed controller through `to_ss()`."""),
    ("code", r"""N, t_change = 1600, 45.0
Fp, Gp, Hp, _ = (np.asarray(m) for m in control.ssdata(control.ss(ds.plant)))


def motor_update(t, x, u, params):
    gain = 5.0 if t >= t_change else 1.0                    # the load change
    return Fp @ x + Gp[:, 0] * gain * u[0]


def motor_output(t, x, u, params):
    return Hp @ x + u[1]                                    # measurement noise


motor = control.nlsys(motor_update, motor_output, inputs=["u", "noise"], outputs=["y"],
                      states=Fp.shape[0], dt=dt, name="motor")
estimator = RecursiveLeastSquares(4, lam=0.98, x0=model.theta_,
                                  P0=np.diag([1e-2, 1e-2, 1e-6, 1e-6]))
stre = SelfTuningRegulator(estimator, design=dict(Am=Am, Ao=Ao), na=2, nb=2, nk=1,
                           initial=ctrl, bounds=([-np.inf, -np.inf, 0.0, 0.0], np.inf), dt=dt)
print(stre)

str_loop = control.interconnect(
    [motor, stre.as_iosystem(name="str", extra_outputs=True)], inputs=["r", "dither", "noise"],
    outputs=["y", "u", "e", "theta[0]", "theta[1]", "theta[2]", "theta[3]"])
fixed_loop = control.interconnect(
    [motor, control.ss(ctrl.to_ss(), inputs=["r", "y"], outputs="u", name="fixed")],
    inputs=["r", "noise"], outputs=["y", "u"])

time = np.arange(N) * dt
ref = np.where((np.arange(N) // 200) % 2 == 0, 1.0, -1.0)   # square wave, period 20 s
dither = 0.2 * np.random.default_rng(7).choice([-1.0, 1.0], N)
noise = 0.002 * np.random.default_rng(4).standard_normal(N)
res_str = control.input_output_response(str_loop, time, [ref, dither, noise])
res_fix = control.input_output_response(fixed_loop, time, [ref, noise])
y_str, u_str, theta_str = res_str.outputs[0], res_str.outputs[1], res_str.outputs[3:].T
y_fix = res_fix.outputs[0]

A_true, B_true = ds.true_model().polynomials()
changed = ctrl.closed_loop(A_true, 5.0 * B_true)
print(f"fixed controller on the changed plant: largest |pole| = {np.abs(changed.poles).max():.3f}")
rms_before = np.sqrt(np.mean((y_str[700:900] - ref[700:900]) ** 2))
rms_end = np.sqrt(np.mean((y_str[-200:] - ref[-200:]) ** 2))
print(f"STR: RMS tracking error {rms_before:.3f} before the change, {rms_end:.3f} at the end")
gain_est = theta_str[-1, 2:].sum() / (1 + theta_str[-1, :2].sum())   # B(1) / A(1)
gain_true = 5 * B_true.sum() / A_true.sum()
print(f"static gain at the end: estimated {gain_est:.4f}, true {gain_true:.4f}")
assert not changed.stable and np.abs(y_fix[-1]) > 1e3 and np.all(np.isfinite(y_str))
np.testing.assert_allclose(gain_est, gain_true, rtol=0.02)"""),
    ("md", r"""The same regulator driven by hand, one `step(y, r)` per sample, gives the same numbers (one
sample of the python-control system *is* one step), and keeps a history for plotting."""),
    ("code", r"""x = np.zeros(motor.nstates)
y_step = np.zeros(N)
for i in range(N):
    y_step[i] = motor.output(time[i], x, [0.0, noise[i]])[0]
    u = stre.step(y_step[i], ref[i], dither=dither[i])
    x = motor.dynamics(time[i], x, [u, noise[i]])
print(f"largest difference step loop - interconnect: {np.max(np.abs(y_step - y_str)):.1e}")
assert np.max(np.abs(y_step - y_str)) < 1e-9
print(stre.history)
b_true = np.where(time[:, None] >= t_change, 5.0, 1.0) * np.asarray(ds.b)
truth = np.column_stack([np.broadcast_to(ds.a, (N, 2)), b_true])
stre.history.plot(true_theta=truth);"""),
    ("code", r"""fig, axes = plt.subplots(3, 1, figsize=(11, 8), sharex=True, layout="constrained")
axes[0].plot(time, ref, "k:", lw=1, label="reference")
axes[0].plot(time, y_fix, lw=1, label="fixed controller")
axes[0].plot(time, y_str, lw=1, label="self-tuning regulator")
axes[0].set(ylabel="speed y", ylim=(-2, 2), title="Motor gain x5 at t = 45 s")
axes[0].legend(ncol=3, loc="lower left")
axes[1].plot(time, u_str, lw=0.8, color="C2")
axes[1].set(ylabel="voltage u (STR)")
axes[2].plot(time, theta_str[:, 2] / ds.b[0], label=r"$\hat b_1 / b_1^{before}$")
axes[2].plot(time, theta_str[:, 3] / ds.b[1], label=r"$\hat b_2 / b_2^{before}$")
axes[2].axhline(5, color="k", ls=":", lw=1)
axes[2].set(xlabel="t [s]", ylabel="estimate / initial", ylim=(0, 7))
axes[2].legend(loc="upper left")
for ax in axes:
    ax.axvline(t_change, color="0.6", lw=0.8)"""),
    ("md", r"""The fixed controller, tuned for the old gain, loses stability when the gain grows five-fold;
the self-tuning regulator re-identifies the gain within a few reference steps and keeps the
designed closed-loop behaviour. Three practical points are visible: the loop needs excitation
to identify (the dither and the reference steps; the regulator's excitation monitor warns when
they are missing); the forgetting factor sets how fast the estimate, and with it the
controller, can follow the plant ([notebook 2](02_tracking.ipynb)); and with measurement noise
(not the equation error the ARX model assumes) the individual coefficients are biased, while the
static gain, which the control relies on most, is estimated well ([notebook 3](03_validation.ipynb)
shows how the residual tests reveal such coloured noise)."""),
]

# ----------------------------------------------------------------------
# 6. Real records
# ----------------------------------------------------------------------
REAL_RECORDS = [
    ("md", r"""# 6. Real records: operating point, delay, orders, fresh data, saved model

Measured records are not textbook experiments. They sit on an operating point, the plant has a
dead time, the data come in several runs, and a model is only believed once it reproduces a run
it was not fitted on. This notebook takes `rlsfilt.datasets.heat_exchanger` through the whole
workflow:

1. look at the record (an `IOData` of two runs);
2. remove the operating point (`detrend`, or a model with an `offset`);
3. estimate the delay (`delayest`);
4. choose the orders on validation data (`select_order`);
5. validate on fresh data, with stability said plainly;
6. read the model in continuous time (`d2c`) and save it.

The record is simulated (a steam-heated exchanger: liquid flow in % to outlet temperature in
degC, $K = -0.6$ degC/%, time constants 15 s and 4 s, 7 s of transport delay, sampled every
second), so every step can be checked against the truth."""),
    ("code", r"""import os
import tempfile
import textwrap
import warnings

import control
import matplotlib.pyplot as plt
import numpy as np

from rlsfilt import ARX, delayest, detrend, select_order, validate
from rlsfilt.datasets import heat_exchanger

plt.rcParams.update({"figure.dpi": 150, "savefig.dpi": 150})   # sharp figures
ds = heat_exchanger()
ds"""),
    ("code", r"""fig = ds.plot()
fig.suptitle("Two runs around 40 % flow and 97 degC")
plt.show()"""),
    ("md", r"""## 1. The operating point

An ARX model has no constant term: fitted on signals around 97 degC and 40 %, its parameters
mostly describe the operating point. On the first run the static gain comes out with the wrong
sign and the model is unstable, so its simulation diverges. The fit and `validate` both warn
about the ignored operating point, and the report states the instability instead of a huge
negative fit."""),
    ("code", r"""run1, run2 = ds.getexp("run1"), ds.getexp("run2")
with warnings.catch_warnings(record=True) as caught:   # shown below, as sentences
    warnings.simplefilter("always")
    raw = ARX(2, 2, 8, dt=ds.dt).fit(run1)
    raw_report = validate(raw, run2)
print("static gain of the raw model:", round(raw.dc_gain(), 3), "(true: -0.6)")
print(raw.stability_text())
for w in caught:
    print(textwrap.fill(f"{w.category.__name__}: {w.message}", width=90))
print("\n".join(str(raw_report.summary()).splitlines()[2:4]))"""),
    ("md", r"""`detrend` removes the means (or a line per segment, `type="linear"`) of every signal of every
run, as `scipy.signal.detrend` does, and returns the `Trend` that `retrend` puts back. A model
can also keep the operating point itself: `offset="mean"` removes the estimation means and
adds them back when it predicts, `offset=True` estimates an intercept. Both predict and
simulate in degC."""),
    ("code", r"""run1_d, trend = detrend(run1)
print("operating point of run 1:", trend.input_offset, trend.output_offset)
for offset in ("mean", True):
    m = ARX(2, 2, 8, dt=ds.dt, offset=offset).fit(run1)
    print(f"offset={offset!r:7}: static gain {m.dc_gain():.3f}, {m.stability_text()}, "
          f"operating point {m.output_offset_[0]:.2f} degC")

fig, ax = plt.subplots(figsize=(9, 3), layout="constrained")
ax.plot(run1.t, run1.y - trend.output_offset[0], color="0.6", lw=0.8,
        label="measured T_out - mean")
ax.plot(run1.t, run1_d.y, color="C0", lw=0.8, ls="--", label="detrend(run1).y")
ax.set_xlabel("time (s)")
ax.set_ylabel("deviation (degC)")
ax.legend(loc="upper right")
plt.show()"""),
    ("md", r"""## 2. The delay

`delayest` fits ARX(2, 2, nk) models for every delay in a range, all from one QR factorization
of a wide regressor matrix, and returns the delay with the smallest loss. With the zero-order
hold's own sample, 7 s of transport delay is $n_k = 8$."""),
    ("code", r"""est = delayest(detrend(ds)[0], full_output=True)   # both runs, each about its mean
print("estimated delay:", est.nk)
fig, ax = plt.subplots(figsize=(7, 3), layout="constrained")
ax.semilogy(list(est.nk_range[0]), est.losses[0], "o-")
ax.axvline(est.nk, color="C3", ls=":", label=f"nk = {est.nk}")
ax.set_xlabel("delay $n_k$ (samples)")
ax.set_ylabel("loss $V$ of ARX(2, 2, $n_k$)")
ax.legend()
plt.show()"""),
    ("md", r"""## 3. The orders, chosen on fresh data

`split(0.7)` keeps the first 70 % of every run for estimation and the rest for validation.
`select_order` takes its delay range independently of the orders (around the estimated delay),
scores every candidate on the validation part, and warns if the best one sits at an edge of the
grid."""),
    ("code", r"""est_data, val_data = ds.split(0.7)
sel = select_order(est_data, na=range(1, 5), nb=range(1, 5), nk=range(est.nk - 2, est.nk + 3),
                   validation=val_data, offset="mean", dt=ds.dt)
print(sel.summary(top=5))
sel.plot()
plt.show()"""),
    ("md", r"""## 4. Validation on fresh data

The best model, fitted on the estimation parts of both runs (no regressor row straddles the two),
is simulated on each validation part from its own start."""),
    ("code", r"""model = sel.best_model()
report = validate(model, val_data)
print(str(report.summary()).split("Parameters")[0])
report.plot()
plt.show()"""),
    ("md", r"""Stability is said plainly: `model.poles()`, `model.is_stable`, `model.dc_gain()`, and in every
report. On the raw (not detrended) record the best BIC candidate is unstable; `stable_only=True`
restricts the choice to stable candidates."""),
    ("code", r"""grid = dict(na=range(1, 6), nb=range(1, 6), nk=range(6, 11))
raw_sel = select_order(run1, **grid)
i = raw_sel.best_index
print("raw record, best by BIC:", raw_sel.best,
      "largest pole", round(raw_sel.table["max_pole"][i], 4))
with warnings.catch_warnings():
    # the stable best sits at the grid's edge on raw data, and its refit on the raw record
    # warns about the operating point (as the first fit above did)
    warnings.simplefilter("ignore")
    safe = select_order(run1, **grid, stable_only=True)
    safe_text = safe.best_model().stability_text()
print("with stable_only:", safe.best, safe_text)
print("with the operating point handled:", select_order(run1, **grid, offset=True).best)"""),
    ("md", r"""## 5. Continuous time

`model.to_tf(continuous=True)` inverts the zero-order-hold sampling (`rlsfilt.d2c`, the matrix
logarithm); the whole samples of delay stay an explicit `input_delay`. The signal names of the
record become python-control's labels. Against the true plant:"""),
    ("code", r"""Gc = model.to_tf(continuous=True)
print(Gc)
print("input delay:", Gc.input_delay, "s; static gain:", round(float(Gc(0).real), 3))
true = control.tf([-0.6], [60.0, 19.0, 1.0])
w = np.logspace(-3, 0, 200)
fig, ax = plt.subplots(figsize=(7, 3.5), layout="constrained")
ax.loglog(w, np.abs(true(1j * w)), "k-", lw=2, label="true plant")
ax.loglog(w, np.abs(Gc(1j * w)), "C1--", label=f"identified {model._orders_text()}")
ax.set_xlabel("frequency (rad/s)")
ax.set_ylabel("|G(jw)| (degC / %)")
ax.legend()
plt.show()"""),
    ("md", r"""## 6. Saving the model

`model.save(path)` writes JSON (orders, sampling period, names and units, parameters, their
covariance, the noise variance, the operating point, a version tag); `ARX.load(path)` gives back
a model that predicts, simulates and reports standard errors exactly as the saved one. Nothing
in the file is executed when it is read."""),
    ("code", r"""path = os.path.join(tempfile.mkdtemp(), "exchanger.json")
model.save(path)
back = ARX.load(path)
run = val_data.getexp("run2")
print("same simulation:", np.array_equal(back.simulate(run.u), model.simulate(run.u)))
print("same standard errors:", np.array_equal(back.std_errors_, model.std_errors_))
print(open(path).read()[:400], "...")"""),
    ("md", r"""The command line does the same in one call, on a CSV file with a time column and a run label:

```bash
rlsfilt identify exchanger.csv -u flow -y T_out --time t --experiment-column run \
    --split 0.7 --select-order --save-model exchanger.json
```

(means removed by default, `--detrend constant`; the delay range centred on what `delayest`
finds, `--delay-range` to set it; `--validation FILE.csv` for another file)."""),
]

# ----------------------------------------------------------------------
# 7. Beyond ARX
# ----------------------------------------------------------------------
BEYOND_ARX = [
    ("md", r"""# 7. Beyond ARX: coloured noise, ARMAX, OE, Box-Jenkins and instrumental variables

ARX assumes that the disturbance enters as white noise filtered by the plant's own denominator,
$A(q)\,y = B(q)\,u + e$. Real disturbances rarely do. When they are coloured, the least-squares
ARX estimate converges to the **wrong** parameters, however long the record; its residuals fail
the whiteness test, and no choice of ARX orders fixes the plant model.

This notebook shows

1. the bias of ARX on a simulated ARMAX plant, and that it does not shrink with more data, while
   ARMAX by prediction error and ARX by instrumental variables converge to the truth;
2. a DC-motor record with a slowly drifting disturbance: ARX, IV, output error and Box-Jenkins
   compared on validation data and against the true plant;
3. the recursive forms: recursive prediction error (RPEM) and pseudo-linear regression (RPLR,
   extended least squares), and the positive-realness condition that RPLR needs;
4. a streaming estimator that takes one sample per call;
5. a measured-like record (the heat exchanger of [notebook 6](06_real_records.ipynb): two runs, an operating point, a
   dead time, a drifting disturbance): estimate on one run, validate on the other."""),
    ("code", r"""import warnings

import control
import matplotlib.pyplot as plt
import numpy as np
from scipy.signal import lfilter

from rlsfilt import (ARMA, ARMAX, ARX, BJ, OE, NumericalWarning, RecursiveARMAX, detrend,
                     select_order, select_structure, validate)
from rlsfilt.datasets import dc_motor, heat_exchanger

plt.rcParams.update({"figure.dpi": 150, "savefig.dpi": 150})   # sharp figures
rng = np.random.default_rng(7)"""),
    ("md", r"""## 1. The bias of ARX does not go away

The plant is $y(t) - 1.5\,y(t-1) + 0.7\,y(t-2) = u(t-1) + 0.5\,u(t-2) + e(t) - e(t-1) + 0.2\,e(t-2)$
with white input and noise: an ARMAX system. The ARX equation error $C(q)e(t)$ is a moving
average, correlated with the past outputs in the regressor, so least squares converges to
$\theta^* = R^{-1}E[\varphi y] \ne \theta_0$ (the test suite computes $\theta^*$ exactly from the
plant's covariances: $a^* \approx (-1.227, 0.452)$)."""),
    ("code", r"""a, b, c = [1, -1.5, 0.7], [0, 1, 0.5], [1, -1, 0.2]
print(f"{'N':>7} {'ARX a1':>8} {'IV a1':>8} {'ARMAX a1':>9} {'ARMAX std err':>14}")
for N in (1_000, 10_000, 100_000):
    u, e = rng.standard_normal(N), rng.standard_normal(N)
    y = lfilter(b, a, u) + lfilter(c, a, e)
    arx = ARX(2, 2, 1).fit(u, y)
    iv = ARX(2, 2, 1).fit(u, y, method="iv")         # refined instrumental variables
    armax = ARMAX(2, 2, 2, 1).fit(u, y)              # prediction error, C estimated too
    print(f"{N:>7} {arx.a_[0]:8.3f} {iv.a_[0]:8.3f} {armax.a_[0]:9.3f} {armax.std_errors_[0]:14.4f}")"""),
    ("md", r"""The ARX column settles at $-1.227$, not $-1.5$. The instrumental-variable estimate (the
ARX regressor with the past outputs replaced by the output of an auxiliary model driven by the
input alone) and the ARMAX estimate approach the truth at the rate of their standard errors.
The ARMAX summary shows the noise model $C(q)$ it found:"""),
    ("code", r"""print(armax.summary())"""),
    ("md", r"""## 2. A DC motor with a drifting disturbance

`datasets.dc_motor(noise="colored")` adds an equation error $e(t)/(1 - 0.9q^{-1})$: the true
system is $y = \frac{B}{A}u + \frac{1}{A(1 - 0.9q^{-1})}e$, a Box-Jenkins model with $n_f = 2$,
$n_d = 3$. Two independent experiments give estimation and validation records; the true plant is
known, so every model can be compared with it."""),
    ("code", r"""est = dc_motor(n_samples=2000, noise="colored", rng=0)
val = dc_motor(n_samples=2000, noise="colored", rng=1)
dt = est.dt
models = {
    "ARX(2, 2, 1)": ARX(2, 2, 1, dt=dt).fit(est.u, est.y),
    "ARX, IV": ARX(2, 2, 1, dt=dt).fit(est.u, est.y, method="iv"),
    "OE(2, 2, 1)": OE(2, 2, 1, dt=dt).fit(est.u, est.y),
    "BJ(2, 0, 3, 2, 1)": BJ(2, 0, 3, 2, 1, dt=dt).fit(est.u, est.y),
}
print(f"{'model':18} {'white':>6} {'indep.':>7} {'DC gain':>8} {'freq. error':>12}")
print(f"{'true plant':18} {'':>6} {'':>7} {val.plant.dcgain():8.4f}")
for name, m in models.items():
    rep = validate(m, val.u, val.y, plant=val.plant)
    r = rep.residuals[0]
    print(f"{name:18} {str(r.is_white):>6} {str(r.is_independent):>7} "
          f"{m.to_tf().dcgain():8.4f} {rep.plant_comparison.frequency_error:12.3f}")"""),
    ("md", r"""- ARX is biased (its DC gain is 8 % high) and its residuals are neither white nor
  independent of the input.
- IV and OE give the same plant model here (the refined IV iteration converges to the
  output-error estimate): consistent, residuals independent of the input, but coloured, and
  inefficient: the drifting disturbance is left in the residuals, and the high-frequency part of
  the response (where the PRBS held two samples has little power) is poorly determined.
- Box-Jenkins models the disturbance too ($C/D$): white residuals, independent of the input, and
  the smallest error against the true plant.

The relative error of each frequency response against the truth, $|\hat G - G_0| / |G_0|$ (the
IV curve lies under the OE curve):"""),
    ("code", r"""omega = np.logspace(-1, np.log10(np.pi / dt), 200)
G0 = val.plant(np.exp(1j * omega * dt))
fig, ax = plt.subplots(figsize=(7, 3.5))
for name, m in models.items():
    ax.loglog(omega, np.abs(m.frequency_response(omega)[0, 0] - G0) / np.abs(G0), lw=1.2,
              label=name)
ax.set_xlabel(r"$\omega$ (rad/s)")
ax.set_ylabel(r"$|\hat G - G_0| / |G_0|$")
ax.legend(fontsize=8)
plt.show()"""),
    ("md", r"""Which noise model? `select_structure` fits every Box-Jenkins structure of a grid by prediction
error and ranks them by BIC of the prediction errors (`select_order(u, y, model=BJ, nb=...,
nc=..., nd=..., nf=..., nk=...)` is the same search from the entry point used for ARX):"""),
    ("code", r"""sel = select_structure(BJ, est.u, est.y,
                       {"nb": [2], "nc": [0, 1], "nd": [1, 2, 3], "nf": [2], "nk": [1]}, dt=dt)
print(sel.summary())"""),
    ("md", r"""## 3. Recursive estimation: RPEM and RPLR

`fit(u, y, method="rpem")` runs the recursive prediction-error method: the covariance update of
`RecursiveLeastSquares` with the gradient of the predictor (the pseudo-linear regressor filtered
through $1/C$, $1/F$, $D/C$) in the gain. `method="rplr"` uses the regressor itself: extended
least squares for ARMAX. Both keep the estimate after every sample in `theta_history_`."""),
    ("code", r"""N = 20_000
u, e = rng.standard_normal(N), rng.standard_normal(N)
c_pr = [1, 0.5, 0.2]                       # Re{1/C} > 1/2: both recursions converge
y = lfilter(b, a, u) + lfilter(c_pr, a, e)
fits = {m: ARMAX(2, 2, 2, 1).fit(u, y, method=m) for m in ("rpem", "rplr")}
fig, ax = plt.subplots(figsize=(7, 3.2))
for (m, fit), style in zip(fits.items(), ("-", "--")):
    ax.set_prop_cycle(None)                # the same colour for a parameter in both runs
    ax.plot(fit.theta_history_[:, [0, 1, 4, 5]], style, lw=1)
ax.hlines([-1.5, 0.7, 0.5, 0.2], 0, N, colors="k", lw=0.5)
ax.set_xlabel("sample")
ax.set_ylabel(r"$a_1, a_2, c_1, c_2$")
ax.set_title("RPEM (solid) and RPLR (dashed)")
ax.set_ylim(-2, 1.5)
plt.show()"""),
    ("md", r"""Extended least squares converges only when $\mathrm{Re}\{1/C(e^{i\omega})\} > 1/2$ at every
frequency (Ljung 1977). On Ljung's example $y = (1 + 1.6 q^{-1} + 0.8 q^{-2})\,e$ the condition
fails: RPLR stops short of the truth and warns, RPEM does not."""),
    ("code", r"""y_ma = lfilter([1, 1.6, 0.8], [1], rng.standard_normal(50_000))
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always", NumericalWarning)
    els = ARMA(0, 2).fit(y_ma, method="rplr")
rpem = ARMA(0, 2).fit(y_ma, method="rpem")
print("RPLR:", np.round(els.theta_, 3), "  RPEM:", np.round(rpem.theta_, 3), "  truth: [1.6 0.8]")
print(caught[0].message)"""),
    ("md", r"""## 4. One sample at a time

`RecursiveARMAX` (MATLAB's `recursiveARMAX`) takes `(y, u)` per call and returns the one-step
prediction made before the sample and the updated parameters: the loop of an adaptive
controller or of a monitoring system beside a Kalman filter. It runs the same compiled step as
`fit(method="rpem")`."""),
    ("code", r"""est_online = RecursiveARMAX(2, 2, 2, 1, lam=0.999)
errors = []
for t in range(5000):
    yhat, theta = est_online.step(y[t], u[t])
    errors.append(y[t] - yhat)
print("parameters after 5000 samples:", np.round(theta, 3))
print("mean square prediction error, last 1000 samples:", round(float(np.mean(np.square(errors[-1000:]))), 3))"""),
    ("md", r"""## 5. A measured-like record: the heat exchanger

`datasets.heat_exchanger()` ([notebook 6](06_real_records.ipynb)) holds two runs of a steam-heated exchanger around
40 % flow and 97 degC, with 7 s of transport delay ($n_k = 8$) and a disturbance that drifts
the temperature: $A(q)\,v = e/(1 - 0.9q^{-1})$, so the noise model has the denominator
$A(q)(1 - 0.9q^{-1})$ of order 3 and the true structure is `BJ(2, 0, 3, 2, 8)`. Each run is
taken about its own mean (`detrend`); every model is estimated on run 1 and validated on run 2.
`select_order` with `model=BJ` chooses the order of the noise denominator $D$:"""),
    ("code", r"""ds = heat_exchanger()
hx, _ = detrend(ds)                       # each run about its own operating point
run1, run2 = hx.getexp("run1"), hx.getexp("run2")
sel_bj = select_order(run1, model=BJ, nb=[2], nc=[0, 1], nd=[1, 2, 3, 4], nf=[2], nk=[8],
                      dt=ds.dt)
print(sel_bj.summary(top=4))"""),
    ("md", r"""The residual tests on run 2 (whiteness: the portmanteau test on the residual
autocorrelation; independence: on the cross-correlation with the input; a p-value below 0.05
fails):"""),
    ("code", r"""hx_models = {
    "ARX(2, 2, 8)": ARX(2, 2, 8, dt=ds.dt).fit(run1),
    "ARX(2, 2, 8), IV": ARX(2, 2, 8, dt=ds.dt).fit(run1, method="iv"),
    "ARMAX(2, 2, 2, 8)": ARMAX(2, 2, 2, 8, dt=ds.dt).fit(run1),
    "OE(2, 2, 8)": OE(2, 2, 8, dt=ds.dt).fit(run1),
    "BJ, selected": sel_bj.best_model,
}
print(f"{'model':18} {'p white':>9} {'p indep.':>9} {'DC gain':>8} {'sim. fit %':>10}")
print(f"{'true plant':18} {'':>9} {'':>9} {-0.6:8.3f}")
hx_p = {}
for name, m in hx_models.items():
    rep = validate(m, run2)
    r = rep.residuals[0]
    hx_p[name] = (r.pvalue_white, r.pvalue_independent)
    print(f"{name:18} {r.pvalue_white:9.2g} {r.pvalue_independent:9.2g} {m.dc_gain():8.3f} "
          f"{rep.simulation_fit:10.1f}")"""),
    ("md", r"""What these numbers say, and what they do not:

- ARX's residuals on run 2 fail both tests by a wide margin. Its static gain is nevertheless
  close to the truth on this record, and its simulation fit is as good as any model's: the
  failure is the disturbance description (ARX forces the noise model $1/A$), not a grossly
  wrong plant.
- IV changes the plant estimate (the same as OE here) but an IV model is still an ARX
  predictor: its one-step residuals are the equation errors and fail both tests too.
- ARMAX ($C/A$ for the noise) improves the residuals but still fails: a moving average cannot
  describe a drift with a pole at 0.9.
- OE leaves the drift in the residuals (whiteness fails) but they are independent of the
  input: the plant model is not contradicted.
- Box-Jenkins with the selected noise denominator passes both tests; it is the only model here
  whose residuals are consistent with white noise on data it was not fitted on.

The simulation fits differ by less than a percent: on a record where the drift is small
compared with the response to the input, the residual tests, not the fit, tell the models
apart."""),
    ("code", r"""assert hx_p["ARX(2, 2, 8)"][0] < 0.05 and hx_p["ARX(2, 2, 8)"][1] < 0.05
assert min(hx_p["BJ, selected"]) > 0.05   # the prose above says so: keep it true""",
     {"tags": ["remove-cell"]}),
]

# ----------------------------------------------------------------------
# 8. Time-varying parameters: tuned, detected, smoothed
# ----------------------------------------------------------------------
TIME_VARYING = [
    ("md", r"""# 8. Time-varying parameters: tune, detect, smooth

A first-order plant whose gain drifts slowly and whose pole jumps twice. Every recursive
estimator tracks it with a forgetting factor that somebody has to choose ("typically 0.97 to
0.995"). Here the choice is made by the data instead:

1. **tune** the forgetting factor, or the random walk $Q$, by maximum likelihood
   (`ARX.fit(method="rls", lam="tune")`), and see how sure the estimate is (its profile
   likelihood);
2. **detect** the jumps on the normalized innovations $y_t / \sqrt{S_t}$ of the tuned filter
   (`ChangeDetector`), which reopens its covariance at each alarm;
3. **smooth** each segment between the alarms in both directions (the Rauch-Tung-Striebel
   smoother, `smooth()`);

and compare every step with a hand-picked $\lambda$."""),
    ("code", r"""import numpy as np
import matplotlib.pyplot as plt

from rlsfilt import ARX, RecursiveLeastSquares
from rlsfilt.plotting import plot_smoothed
from rlsfilt.validation import ChangeDetector

plt.rcParams.update({"figure.dpi": 150, "savefig.dpi": 150})   # sharp figures
rng = np.random.default_rng(8)"""),
    ("md", r"""## The plant

$y(t) + a_1(t)\, y(t-1) = b_1(t)\, u(t-1) + e(t)$ with $e$ white, standard deviation 0.2. The pole
$-a_1$ jumps from 0.6 to 0.8 at $t = 1000$ and to 0.5 at $t = 2000$; the gain $b_1$ is a random walk
(steps of standard deviation 0.002). The input is a random binary signal about 1, so the
regressors have a mean and a jump shifts the mean of the innovations."""),
    ("code", r"""N = 3000
t = np.arange(N)
a1 = np.where(t < 1000, -0.6, np.where(t < 2000, -0.8, -0.5))    # the pole jumps twice
b1 = 1.0 + np.cumsum(0.002 * rng.standard_normal(N))              # the gain drifts
u = 1.0 + np.where(rng.random(N) < 0.5, -0.5, 0.5)                 # binary, about 1
y = np.zeros(N)
for k in range(1, N):
    y[k] = -a1[k] * y[k - 1] + b1[k] * u[k - 1] + 0.2 * rng.standard_normal()

theta_true = np.column_stack([a1, b1])[1:]      # on the regressor rows t = 1 .. N-1


def rms(theta):
    "RMS tracking error of a1 and b1 after the first 200 rows."
    return np.sqrt(np.mean((theta[200:] - theta_true[200:]) ** 2, axis=0))"""),
    ("md", r"""## Hand-picked forgetting factors

`ARX(1, 1).fit(u, y, method="rls", lam=...)` for the usual range of $\lambda$; `theta_history_`
holds the estimate after every sample:"""),
    ("code", r"""print(f"{'lam':>8} {'RMS a1':>8} {'RMS b1':>8}")
by_hand = {}
for lam in (0.9, 0.95, 0.98, 0.99, 0.995):
    by_hand[lam] = ARX(1, 1).fit(u, y, "rls", lam=lam)
    print(f"{lam:8.3f} " + " ".join(f"{v:8.4f}" for v in rms(by_hand[lam].theta_history_)))"""),
    ("md", r"""The errors depend strongly on $\lambda$, and the best value is not the textbook one. Nothing in
these numbers is available without the true parameters."""),
    ("md", r"""## 1. Tune by maximum likelihood

The filter is the Kalman filter of the parameters, so its innovations give the exact Gaussian
log-likelihood of the record (the prediction-error decomposition), with the noise variance $R$
in closed form. `lam="tune"` maximizes it over $\lambda$ before the fit; `tune_` holds the
estimate, its standard error and its 95 % interval:"""),
    ("code", r"""tuned_lam = ARX(1, 1).fit(u, y, "rls", lam="tune")
print(tuned_lam.tune_.summary())
print("RMS a1, b1:", np.round(rms(tuned_lam.theta_history_), 4))"""),
    ("md", r"""The profile likelihood shows how sharply the data pin $\lambda$ down: the 95 %
likelihood-ratio interval is where the curve stays within 1.92 of its maximum."""),
    ("code", r"""ax = tuned_lam.tune_.plot_profile()
plt.show()
lo, hi = tuned_lam.tune_.likelihood_interval()
print(f"95 % likelihood interval of lam: [{lo:.4f}, {hi:.4f}]")
print("log-likelihood of the hand-picked values, relative to the maximum:")
for lam in by_hand:
    print(f"  lam = {lam:5.3f}: {tuned_lam.tune_.profile(lam) - tuned_lam.tune_.loglik:9.1f}")"""),
    ("md", r"""Forgetting discounts the whole covariance at the same rate. A random walk $Q$ adds
uncertainty without forgetting the information already gathered; `Q="tune"` estimates its
size $q$ the same way ($Q = q R I$ for the record scaled to unit size: each coefficient's step
relative to its regressor's size; `tune_.apply` sets its image for the filter below), and its
likelihood is higher:"""),
    ("code", r"""tuned_q = ARX(1, 1).fit(u, y, "rls", Q="tune")
print(tuned_q.tune_.summary())
print("RMS a1, b1:", np.round(rms(tuned_q.theta_history_), 4))
print("log-likelihood gain over the tuned lam:",
      round(tuned_q.tune_.loglik - tuned_lam.tune_.loglik, 1))"""),
    ("md", r"""## 2. Find the jumps

The tuned filter's normalized innovations $y_t / \sqrt{S_t}$ are $N(0, 1)$ while the model
holds. A two-sided CUSUM on them (`ChangeDetector`, threshold set for one false alarm per
10,000 samples on average) alarms when a jump shifts their mean, and `action="boost"`
multiplies $P$ by 1000 at each alarm so the filter re-converges at once. The filter runs on
the model's regressor rows, one sample at a time:"""),
    ("code", r"""Phi, target = ARX(1, 1).regressors(u, y)

online = tuned_q.tune_.apply(RecursiveLeastSquares(2, P0=1e4))   # the fit's Q, R estimated
detector = ChangeDetector("cusum", arl=10_000, shift=1.0, action="boost")
detected = np.empty((len(target), 2))
for k in range(len(target)):
    online.predict_update(target[k], Phi[k])
    detector.step(online)                      # reads online.y and online.S
    detected[k] = online.x[:, 0]
alarms = np.array(detector.alarms)
print("alarms at t =", alarms + 1, "(the jumps are at t = 1000 and 2000)")
print("RMS a1, b1:", np.round(rms(detected), 4))"""),
    ("code", r"""assert len(alarms) == 2 and abs(alarms[0] + 1 - 1000) <= 10 and abs(alarms[1] + 1 - 2000) <= 10""",
     {"tags": ["remove-cell"]}),
    ("md", r"""## 3. Smooth each segment

Between the alarms the parameters barely move. Each segment is tuned again (a diagonal $Q$: one
random walk per parameter; both end near zero here, constant parameters fit the data) and
smoothed in both directions: every estimate then uses the whole segment, not only the past."""),
    ("code", r"""edges = [0, *alarms, len(target)]
pieces = []
for lo, hi in zip(edges[:-1], edges[1:]):
    fit = RecursiveLeastSquares(2, P0=1e4).tune(target[lo:hi], Phi[lo:hi], "q_diag", burn=2)
    print(f"rows {lo:4d}-{hi:4d}: q = {np.array2string(fit.estimate, precision=2)}")
    pieces.append(fit.apply(RecursiveLeastSquares(2, P0=1e4)).smooth(target[lo:hi], Phi[lo:hi]))
smoothed = np.vstack([p.means[:, :, 0] for p in pieces])
print("RMS a1, b1:", np.round(rms(smoothed), 4))"""),
    ("code", r"""ax = plot_smoothed(pieces[1], names=["$a_1$", "$b_1$"],
                   true_values=theta_true[edges[1]:edges[2]])
ax.set_xlabel("row of the second segment")
ax.set_ylim(-1.0, 1.2)
plt.show()"""),
    ("md", r"""## The comparison

The hand-picked $\lambda = 0.98$ against each step: the tuned $\lambda$, the tuned random walk,
the random walk with the detector, and the smoothed segments."""),
    ("code", r"""runs = {
    "lam = 0.98 (by hand)": by_hand[0.98].theta_history_,
    f"lam = {tuned_lam.lam_:.3f} (tuned)": tuned_lam.theta_history_,
    f"Q with q = {tuned_q.tune_.estimate:.1e} (tuned)": tuned_q.theta_history_,
    "tuned Q + detector": detected,
    "smoothed segments": smoothed,
}
print(f"{'':28} {'RMS a1':>8} {'RMS b1':>8}")
for name, theta in runs.items():
    print(f"{name:28} " + " ".join(f"{v:8.4f}" for v in rms(theta)))

fig, axes = plt.subplots(2, 1, figsize=(8, 5), sharex=True, layout="constrained")
rows = np.arange(1, N)
for i, (axis, label) in enumerate(zip(axes, ["$a_1$", "$b_1$"])):
    axis.plot(rows, theta_true[:, i], color="k", lw=1.5, label="true")
    axis.plot(rows, by_hand[0.98].theta_history_[:, i], lw=0.8, alpha=0.7,
              label=r"$\lambda = 0.98$ by hand")
    axis.plot(rows, detected[:, i], lw=0.8, label="tuned $Q$ + detector")
    axis.plot(rows, smoothed[:, i], lw=1.2, label="smoothed segments")
    for a in alarms:
        axis.axvline(a + 1, color="grey", ls=":", lw=1)
    axis.set_ylabel(label)
axes[0].set_ylim(-1.0, -0.3)
axes[1].set_ylim(0.7, 1.3)
axes[1].set_xlabel("sample $t$")
axes[0].legend(ncol=2, fontsize=7, loc="upper right")
plt.show()"""),
    ("code", r"""errs = {name: rms(theta).sum() for name, theta in runs.items()}
assert errs["smoothed segments"] < errs["tuned Q + detector"] < errs["lam = 0.98 (by hand)"]
assert tuned_q.tune_.loglik > tuned_lam.tune_.loglik""",
     {"tags": ["remove-cell"]}),
    ("md", r"""What the data chose, and what it bought:

- the tuned $\lambda$ is below the textbook range and tracks better than $\lambda = 0.98$; the
  textbook values (0.98 and above) lie far outside its likelihood interval;
- the tuned random walk has a higher likelihood than any forgetting factor and tracks better
  still;
- the detector finds both jumps within a few samples, and reopening the covariance there lets
  a slowly tuned filter follow them;
- smoothing the segments between the alarms, each with its own tuned $Q$, gives the smallest
  errors: every estimate uses the data on both sides.

The guide page *Time-varying parameters* has the equations and the oracles (statsmodels'
maximum likelihood, banded least squares, filterpy's smoother)."""),
]

NOTEBOOKS = {
    "01_quickstart.ipynb": QUICKSTART,
    "02_tracking.ipynb": TRACKING,
    "03_validation.ipynb": VALIDATION,
    "04_control.ipynb": CONTROL,
    "05_beside_filterpy.ipynb": FILTERPY,
    "06_real_records.ipynb": REAL_RECORDS,
    "07_beyond_arx.ipynb": BEYOND_ARX,
    "08_time_varying.ipynb": TIME_VARYING,
}


def build(cells):
    nb = nbformat.v4.new_notebook()
    nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3",
                                 "language": "python"}
    nb.metadata["language_info"] = {"name": "python"}
    for kind, src, *meta in cells:   # an optional third item is the cell's metadata (tags)
        make = nbformat.v4.new_markdown_cell if kind == "md" else nbformat.v4.new_code_cell
        nb.cells.append(make(src.strip("\n"), metadata=meta[0] if meta else {}))
    for i, cell in enumerate(nb.cells):   # stable ids keep diffs small
        cell["id"] = f"cell-{i:02d}"
    return nb


def main(names=None):
    for name, cells in NOTEBOOKS.items():
        if names and name not in names:
            continue
        nbformat.write(build(cells), HERE / name)
        print(f"wrote notebooks/{name}")


if __name__ == "__main__":
    main(sys.argv[1:])
