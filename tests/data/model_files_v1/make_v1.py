"""Model files of format version 1, written by rlsfilt before the schema (commit 42996b6).

Run from a checkout of that commit: python make_v1.py OUTDIR
"""
import os
import sys
import warnings

import numpy as np
from scipy.signal import lfilter

import rlsfilt
from rlsfilt import AR, ARMA, ARMAX, ARX, BJ, OE, IOData, detrend

warnings.simplefilter("ignore")
out = sys.argv[1]
rng = np.random.default_rng(27)
N = 120
U = rng.standard_normal((N, 2))
y = lfilter([0, 1.0, 0.5], [1, -0.5], U[:, 0]) + lfilter([0, 0.3], [1, -0.2], U[:, 1]) \
    + 0.1 * rng.standard_normal(N)
Y2 = np.column_stack([y, lfilter([0, 1], [1, -0.3], U[:, 1]) + 0.1 * rng.standard_normal(N)])
data_d, trend = detrend(IOData(U[:, 0] + 40 + 0.01 * np.arange(N), y + 97, dt=0.5,
                               input_names=["flow"], output_names=["T_out"]), type="linear")
models = {
    "arx_offset_trend": (ARX(2, 2, 1, dt=0.5, offset=True).fit(data_d), {"trend": trend}),
    "arx_mimo": (ARX(1, [1, 2], [1, 0]).fit(U, Y2), {}),
    "arx_rls_data": (ARX(2, 2, 1).fit(U[:, 0], y, method="rls", lam=0.99),
                     {"include_data": True}),
    "arx_iv": (ARX(2, 2, 1).fit(U[:, 0], y, method="iv"), {}),
    "arx_mean": (ARX(1, 2, 1, offset="mean").fit(U[:, 0], y + 3), {}),
    "armax_rplr_miso": (ARMAX(1, [1, 1], 1, [1, 0]).fit(U, y, method="rplr"), {}),
    "oe": (OE(1, 2, 1).fit(U[:, 0], y), {}),
    "bj": (BJ(1, 1, 1, 1, 1).fit(U[:, 0], y), {}),
    "ar": (AR(2).fit(y), {}),
    "arma_rpem": (ARMA(1, 1).fit(y, method="rpem"), {}),
}
for name, (model, kw) in models.items():
    model.save(os.path.join(out, f"{name}.json"), **kw)
print(rlsfilt.__file__)
