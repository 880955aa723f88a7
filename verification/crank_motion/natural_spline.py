"""The natural cubic spline (second derivative zero at both ends) through (x, y), its
first and second derivatives: the textbook construction (e.g. Burden & Faires,
Numerical Analysis, sec. 3.5), to check the motion driven by spline(NAME, t)."""
import numpy as np


def natural_spline(x, y):
    x, y = np.asarray(x, float), np.asarray(y, float)
    n = len(x) - 1
    h = np.diff(x)
    a = np.zeros((n + 1, n + 1))
    b = np.zeros(n + 1)
    a[0, 0] = a[n, n] = 1
    for i in range(1, n):
        a[i, i - 1], a[i, i], a[i, i + 1] = h[i - 1], 2 * (h[i - 1] + h[i]), h[i]
        b[i] = 6 * ((y[i + 1] - y[i]) / h[i] - (y[i] - y[i - 1]) / h[i - 1])
    m = np.linalg.solve(a, b)  # second derivatives at the points

    def evaluate(t):
        t = np.asarray(t, float)
        k = np.clip(np.searchsorted(x, t, side="right") - 1, 0, n - 1)
        hk, u, w = h[k], x[k + 1] - t, t - x[k]
        s = (m[k] * u**3 + m[k + 1] * w**3) / (6 * hk) + (y[k] / hk - m[k] * hk / 6) * u + \
            (y[k + 1] / hk - m[k + 1] * hk / 6) * w
        d1 = (-m[k] * u**2 + m[k + 1] * w**2) / (2 * hk) - (y[k] / hk - m[k] * hk / 6) + \
            (y[k + 1] / hk - m[k + 1] * hk / 6)
        d2 = (m[k] * u + m[k + 1] * w) / hk
        return s, d1, d2
    return evaluate
