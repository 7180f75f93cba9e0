#!/usr/bin/python3
"""Reference figures for clearfit's study analyses, from scikit-learn and SciPy.

Reads X (n x p) and y from a CSV (last column y, no header), writes JSON with
scikit-learn's PLSRegression(n_components=A, scale=True) predictions, x_weights_,
coefficients in original units, R^2, VIP (computed from its attributes), and
scipy.stats.linregress of y on the first column."""
import json
import sys

import numpy as np
from scipy import stats
from sklearn.cross_decomposition import PLSRegression

data = np.loadtxt(sys.argv[1], delimiter=",", ndmin=2)
components = int(sys.argv[2])
x, y = data[:, :-1], data[:, -1]
pls = PLSRegression(n_components=components, scale=True).fit(x, y)
pred = pls.predict(x).ravel()
w, t, q = pls.x_weights_, pls.x_scores_, pls.y_loadings_.ravel()
ss = q**2 * (t**2).sum(axis=0)
vip = np.sqrt(x.shape[1] * ((w / np.linalg.norm(w, axis=0)) ** 2 @ ss) / ss.sum())
lin = stats.linregress(x[:, 0], y)
json.dump({
    "predict": pred.tolist(),
    "x_weights": w.T.tolist(),
    "r2": float(pls.score(x, y)),
    "vip": vip.tolist(),
    "linregress": {"slope": lin.slope, "intercept": lin.intercept, "r2": lin.rvalue**2, "p": lin.pvalue,
                   "slope_se": lin.stderr},
}, sys.stdout)
