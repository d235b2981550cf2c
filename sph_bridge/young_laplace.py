"""Static sessile drops from the Young-Laplace equation: the reference shapes for the droplet
case (seed 000 §3.1; digest §5.1).

The free surface has curvature kappa = 2/b + z / lambda_c^2 with z the depth below the apex,
b the apex radius and lambda_c = sqrt(sigma / (rho g)) (Eq. 36). Along the arc length s from
the apex, with phi the surface's angle to the horizontal,

    dx/ds = cos phi,  dz/ds = sin phi,  dphi/ds = kappa - (sin phi / x for an axisymmetric drop)

and the profile ends where phi reaches the contact angle. A ridge (a 2-D drop, long along y)
has no azimuthal curvature term. Its height tends to de Gennes' puddle height
2 lambda_c sin(theta/2) (Eq. 37) exponentially in its width over lambda_c; an axisymmetric
drop's overshoots it by ~lambda_c / (2a) at base radius a (6 % at a = 8 lambda_c). Without
gravity both are circular caps: height / width = tan(theta/2) / 2.
"""

from __future__ import annotations

import math

from scipy.integrate import solve_ivp
from scipy.optimize import brentq


def profile_end(apex_radius: float, theta_deg: float, capillary_length: float, axisymmetric: bool):
    """(base half-width, height, volume) of the profile with apex radius b; the volume is per unit
    length for a ridge. ``capillary_length`` = inf means no gravity."""
    theta = math.radians(theta_deg)
    inv_lc2 = 0.0 if math.isinf(capillary_length) else 1.0 / capillary_length**2

    def rhs(_, y):
        x, z, phi, _vol = y
        kappa = 2.0 / apex_radius if axisymmetric else 1.0 / apex_radius
        kappa += z * inv_lc2
        if axisymmetric:
            kappa -= math.sin(phi) / x if x > 1e-12 * apex_radius else 1.0 / apex_radius
        dvol = math.pi * x * x * math.sin(phi) if axisymmetric else 2.0 * x * math.sin(phi)
        return [math.cos(phi), math.sin(phi), kappa, dvol]

    def reached(_, y):
        return y[2] - theta

    reached.terminal = True
    scale = min(apex_radius, capillary_length)
    sol = solve_ivp(rhs, [0.0, 50.0 * max(apex_radius, scale)], [0.0, 0.0, 0.0, 0.0], events=reached,
                    rtol=1e-10, atol=1e-14 * scale, max_step=scale / 50.0)
    if not len(sol.y_events[0]):
        raise ValueError("the profile never reaches the contact angle")
    x, z, _, vol = sol.y_events[0][0]  # the drop at depth z is a disc (strip) of half-width x
    return x, z, vol


def sessile_height(volume: float, theta_deg: float, capillary_length: float, axisymmetric: bool = True):
    """(height, base width) of the static drop holding ``volume`` (per unit length for a ridge)."""
    if not 0.0 < theta_deg < 180.0:
        raise ValueError("contact angle must be in (0, 180) degrees")

    def excess(log_b):
        return profile_end(math.exp(log_b), theta_deg, capillary_length, axisymmetric)[2] - volume

    size = volume ** (1.0 / 3.0) if axisymmetric else math.sqrt(volume)
    lo, hi = math.log(size * 1e-3), math.log(size * 1e3)
    first = lo
    # a puddle's width grows only as lambda_c ln(b / lambda_c) with its apex radius b
    while excess(hi) < 0.0:
        if hi > first + 200.0:
            raise ValueError("no Young-Laplace drop holds that volume")
        lo, hi = hi, hi + 10.0
    log_b = brentq(excess, lo, hi, xtol=1e-12)
    half_width, height, _ = profile_end(math.exp(log_b), theta_deg, capillary_length, axisymmetric)
    return height, 2.0 * half_width
