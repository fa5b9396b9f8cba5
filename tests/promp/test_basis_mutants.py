"""Gaussian basis: the behaviours `make mutate` found untested (issue 20)."""
import numpy as np
import pytest

from drake_skills.promp.basis import GaussianBasis


def test_phi_tolerance_of_1e_9_is_inclusive_and_the_next_float_beyond_it_is_rejected():
    b = GaussianBasis(4)
    lo, hi = -1e-9, 1 + 1e-9
    # exactly at the tolerance: accepted, and Phi is the Gaussians evaluated there
    np.testing.assert_allclose(b.phi([lo, hi]), np.exp(-0.5 * ((np.array([[lo], [hi]]) - b.centers) / b.sigma) ** 2),
                               rtol=1e-15, atol=0)
    with pytest.raises(ValueError, match=r"^phase must lie in \[0, 1\], got \[-1e-09, 0.5\]$"):
        b.phi([np.nextafter(lo, -1.0), 0.5])
    with pytest.raises(ValueError, match=r"^phase must lie in \[0, 1\], got \[0.5, 1\]$"):
        b.phi([0.5, np.nextafter(hi, 2.0)])
