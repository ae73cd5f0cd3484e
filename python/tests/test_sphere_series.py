"""The rigid sphere's transfer functions (afe.transfer, issue 59) against the scattering
series computed here, independently, with scipy's spherical Bessel functions: Rayleigh's
rigid sphere in a plane wave, and a point source at a distance, each over the free field
at the centre. Within 1e-6 relative at every frequency and direction tried."""

import numpy as np
import pytest
from scipy.special import eval_legendre, spherical_jn, spherical_yn

import afe

C = 343.0  # m/s, as afe's sphere


def hankel(m, x, derivative=False):
    """Spherical Hankel function of the first kind (time convention exp(-i w t))."""
    return spherical_jn(m, x, derivative) + 1j * spherical_yn(m, x, derivative)


def surface_pressure(radius, distance, cos_angle, f):
    """Total pressure on the rigid sphere at the point `cos_angle` away from the source
    direction, over the free-field pressure at the centre, in the DFT's convention.

    With the Wronskian j_m h_m' - j_m' h_m = i/x^2, the incident plus scattered field on
    the surface of order m is i/(ka)^2/h_m'(ka) times the incident field's coefficient:
    for a plane wave from the source direction, i^m (2m+1) P_m(-cos); for a point source
    at r, ik h_m(kr) (2m+1) P_m(cos) over 4 pi, and the free field exp(ikr)/(4 pi r)."""
    k = 2 * np.pi * f / C
    ka = k * radius
    total = 0j
    for m in range(400):
        dh = hankel(m, ka, derivative=True)
        if np.isinf(dh):
            break
        if np.isinf(distance):
            term = 1j**m * (2 * m + 1) * eval_legendre(m, -cos_angle) * 1j / (ka**2 * dh)
        else:
            h = hankel(m, k * distance)
            term = (2 * m + 1) * eval_legendre(m, cos_angle) * 1j * k * h * 1j / (ka**2 * dh)
        if not np.isfinite(term):
            break
        total += term
        if m > ka + 30 and abs(term) < 1e-17 * abs(total):
            break
    if not np.isinf(distance):
        total /= np.exp(1j * k * distance) / distance
    # afe's spectra follow the DFT (a delay is exp(-i w tau)): the conjugate of exp(-i w t)
    return np.conj(total)


@pytest.mark.parametrize(
    "head,radius,ears,distance",
    [
        ("sphere", 0.075, 90.0, np.inf),
        ("sphere:radius=0.0875,ears=100", 0.0875, 100.0, np.inf),
        ("sphere:radius=0.075,distance=0.5", 0.075, 90.0, 0.5),
        ("sphere:radius=0.09,ears=80,distance=0.2", 0.09, 80.0, 0.2),
    ],
)
def test_the_sphere_matches_the_series_within_1e_6(head, radius, ears, distance):
    freqs = np.array([50.0, 200.0, 700.0, 1500.0, 3000.0, 6000.0, 11000.0, 20000.0])
    worst = 0.0
    for az in [0.0, 30.0, 90.0, 135.0, 200.0, 290.0]:
        h = afe.transfer(freqs, az, head=head)
        assert h.shape == (len(freqs), 2) and h.dtype == np.complex128
        for ear, ear_deg in enumerate([ears, -ears]):
            cos_angle = np.cos(np.radians(az - ear_deg))
            for f, got in zip(freqs, h[:, ear]):
                want = surface_pressure(radius, distance, cos_angle, f)
                rel = abs(got - want) / abs(want)
                worst = max(worst, rel)
                assert rel < 1e-6, (az, ear, f, got, want)
    print(f"{head}: worst relative difference {worst:.1e}")


def test_transfer_names_what_it_cannot_do():
    with pytest.raises(ValueError, match="unknown head 'cube'"):
        afe.transfer([100.0], 0.0, head="cube")
    with pytest.raises(ValueError, match="frequency -5 Hz"):
        afe.transfer([100.0, -5.0], 0.0)
    with pytest.raises(ValueError, match="a vector of frequencies"):
        afe.transfer([[100.0]], 0.0)
