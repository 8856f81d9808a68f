"""How far a glint spreads: a light of real size and a surface of real gloss.

A point light on a perfect mirror glints only where the wall's normal is the
half vector h exactly. A real light fills a small disc of directions, and a
real surface's microfacets tilt about its mean normal, so a wall also glints
where its normal is a little off h. Along a groove the wall's normal turns
with the groove's tangent, so the glint becomes a streak along the groove;
across it the wall's normal turns fast (the ball's radius), so it stays thin.

What decides the streak is how far the normal may stray from h along the
groove, the angle psi = asin(h . t / |h|) for the groove's tangent t. Its
spread is the sum of two independent parts:

- the light's disc: a light direction moved by delta moves h by about
  ``k`` delta, with ``k = |P_l P_h t| / |l + v|`` along t (P projects off a
  unit vector; l and v point to the light and the eye). A disc of angular
  radius beta seen along one direction is a semicircle law of radius k beta;
- the gloss: Beckmann microfacets of roughness alpha (as Mitsuba and most
  renderers define it) have slopes Gaussian with standard deviation
  alpha / sqrt(2) along any direction.

Their convolution is the *lobe*: the share of light a wall whose normal is
psi off h along the groove sends to the eye, per radian of psi. It integrates
to one, so a streak's whole brightness is what the point model gives the
glint, and the wall's radius of curvature along the groove spreads it over a
length of the groove.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from specholo.errors import SpecholoError

#: The sun's angular diameter, radians (0.53 degrees).
SUN = math.radians(0.53)
#: Named surfaces and their Beckmann roughness alpha. A diamond-turned or
#: mirror-polished metal or a first-surface mirror is about 0.003; polished
#: sheet about 0.01; satin 0.05. These are typical values for the finishes,
#: not measurements of a particular plate: measure yours with a test coupon.
GLOSS = {"mirror": 0.003, "polished": 0.01, "satin": 0.05}
#: Beyond this many standard deviations of the gloss the lobe is taken as zero.
TAIL = 5.0


@dataclass(frozen=True)
class Spread:
    """A light's size and a surface's gloss: how far a glint spreads.

    Attributes:
        light_size: the light's angular diameter seen from the plate, radians
            (the sun's is :data:`SUN`; an LED's is its diameter over its distance).
        roughness: Beckmann roughness alpha of the plate's surface (0: a mirror).
    """

    light_size: float = 0.0
    roughness: float = 0.0

    def __post_init__(self) -> None:
        for name, v, top in (("light size", self.light_size, math.radians(20.0)),
                             ("roughness", self.roughness, 0.5)):
            if not (math.isfinite(v) and 0.0 <= v <= top):
                raise SpecholoError(f"{name} must be in [0, {_shown(name, top)}], got "
                                    f"{_shown(name, v)}")

    @classmethod
    def of(cls, light_size_deg: float | None, gloss: str | float | None) -> Spread | None:
        """The spread from a command's options: the light's angular diameter in
        degrees and a named gloss (:data:`GLOSS`) or a roughness alpha; None
        where neither is given (every glint a point)."""
        if light_size_deg is None and gloss is None:
            return None
        try:
            alpha = float(gloss) if gloss is not None else 0.0
        except ValueError:  # a name
            if gloss not in GLOSS:
                raise SpecholoError(f"roughness {gloss!r} is neither a number nor one of "
                                    f"{', '.join(GLOSS)}") from None
            alpha = GLOSS[str(gloss)]
        size = float(light_size_deg) if light_size_deg is not None else 0.0
        if not math.isfinite(size):
            raise SpecholoError(f"light size must be a number of degrees, got {size}")
        return cls(math.radians(size), alpha)

    @property
    def is_point(self) -> bool:
        """Whether every glint stays a point (no size, no roughness)."""
        return self.light_size == 0.0 and self.roughness == 0.0

    @property
    def sigma(self) -> float:
        """Standard deviation of the gloss's microfacet slopes along a direction, rad."""
        return self.roughness / math.sqrt(2.0)

    def reach(self, k: np.ndarray | float) -> np.ndarray:
        """How far psi may stray before the lobe is zero, radians, for light factors k."""
        return np.asarray(k, dtype=float) * 0.5 * self.light_size + TAIL * self.sigma

    def mass(self, psi_a: np.ndarray, psi_b: np.ndarray, k: np.ndarray) -> np.ndarray:
        """Mean lobe (per radian) over psi from psi_a to psi_b (g,), light factors k (g,).

        A stretch of wall whose normal sweeps psi_a .. psi_b sends its length
        times this to the eye: the lobe averaged over the sweep, the exact
        share where psi runs linearly along it. (A sweep narrower than a
        thousandth of the lobe takes the lobe at its middle.)
        """
        from specholo.optics._lobe_kernel import lobe_mass

        def flat(v: np.ndarray) -> np.ndarray:
            return np.ascontiguousarray(np.broadcast_to(np.asarray(v, dtype=float),
                                                        np.shape(psi_a)).ravel())

        out = lobe_mass(flat(psi_a), flat(psi_b), flat(k), 0.5 * self.light_size, self.sigma,
                        1e-3)
        return out.reshape(np.shape(psi_a))

    def describe(self) -> str:
        """Words for the light and surface, as a figure's conditions name them."""
        gloss = next((f"{name} (alpha {a:g})" for name, a in GLOSS.items()
                      if a == self.roughness), f"roughness alpha {self.roughness:g}")
        return f"a light {math.degrees(self.light_size):.3g} deg across, {gloss} surface"

    def to_dict(self) -> dict[str, float]:
        """The settings by the command's option names, degrees at the edge."""
        return {"light_size": math.degrees(self.light_size), "roughness": self.roughness}


def _shown(name: str, v: float) -> str:
    return f"{math.degrees(v):g} deg" if name == "light size" else f"{v:g}"
