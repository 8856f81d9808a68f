"""Compiled lobe of a light of real size on a surface of real gloss (see
:mod:`specholo.optics.spread`): the light's disc, a semicircle law of radius
k beta in psi, convolved with the gloss's Gaussian of standard deviation
sigma, each summed exactly over the other's quadrature nodes (the wider part
over the narrower's, so that neither is sampled coarser than it is wide).
"""

from __future__ import annotations

import math

import numpy as np

from specholo._compiling import kernel
from specholo._threads import chunked

#: Fewest cells per thread worth a thread's start.
_GRAIN = 4096


def _nodes() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    x, w = np.polynomial.hermite.hermgauss(NODES)
    theta = np.arange(1, NODES + 1) * math.pi / (NODES + 1)
    cw = np.sin(theta) ** 2
    return x, w / math.sqrt(math.pi), np.cos(theta), cw / cw.sum()


def lobe_mass(psi_a: np.ndarray, psi_b: np.ndarray, k: np.ndarray, beta: float, sigma: float,
              floor: float) -> np.ndarray:
    """(c,) the lobe's mean over psi_a .. psi_b per cell (see
    :meth:`~specholo.optics.spread.Spread.mass`): the light's disc of angular
    radius ``beta`` (times k) convolved with the gloss's Gaussian of standard
    deviation ``sigma``, each summed over the other's nodes. ``floor``: the
    narrowest sweep taken, as a share of the lobe's width."""
    c = len(psi_a)
    out = np.empty(c)
    chunked(_lobe_mass, 0, c, psi_a, psi_b, k, beta, sigma, floor, *_nodes(), out,
            grain=_GRAIN)
    return out


#: Nodes of the sums over the gloss (Gauss-Hermite) and the disc (Gauss-Chebyshev).
NODES = 24


@kernel(helper=True)
def _semicircle_cdf(u: float) -> float:
    u = min(1.0, max(-1.0, u))
    return 0.5 + (u * math.sqrt(1.0 - u * u) + math.asin(u)) / math.pi


@kernel(helper=True)
def _cdf(psi: float, a: float, sigma: float, x: np.ndarray, w: np.ndarray, cos_t: np.ndarray,
         cw: np.ndarray) -> float:
    if sigma == 0.0:
        return _semicircle_cdf(psi / max(a, 1e-300))
    if a == 0.0:
        return 0.5 * math.erfc(-psi / (sigma * math.sqrt(2.0)))
    total = 0.0
    if a > sigma:  # the wider part summed exactly over the narrower's nodes
        for n in range(len(x)):
            total += w[n] * _semicircle_cdf((psi - math.sqrt(2.0) * sigma * x[n]) / a)
    else:
        for n in range(len(cos_t)):
            total += cw[n] * 0.5 * math.erfc(-(psi - a * cos_t[n]) / (sigma * math.sqrt(2.0)))
    return total


@kernel(nogil=True)
def _lobe_mass(lo: int, hi: int, psi_a: np.ndarray, psi_b: np.ndarray, k: np.ndarray,
               beta: float, sigma: float, floor: float, x: np.ndarray, w: np.ndarray,
               cos_t: np.ndarray, cw: np.ndarray, out: np.ndarray) -> None:
    for j in range(lo, hi):
        a = k[j] * beta
        width = a / 5.0 + sigma if sigma > 0.0 else a
        half = max(0.5 * abs(psi_b[j] - psi_a[j]), floor * max(width, 1e-12))
        mid = 0.5 * (psi_a[j] + psi_b[j])
        out[j] = (_cdf(mid + half, a, sigma, x, w, cos_t, cw)
                  - _cdf(mid - half, a, sigma, x, w, cos_t, cw)) / (2.0 * half)

