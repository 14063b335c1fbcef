"""Inputs a lab states, drawn per run: each is the true value plus an error
drawn from a normal distribution with the standard uncertainty the lab
states for it, so the stated u is the true size of the error.

- caliper values of the calibration wedge: u = 0.01 mm each (xgauge's
  `wedge.dimension_uncertainty_mm`, its default);
- the detector's lag fraction: u = a tenth of the true fraction (xgauge's
  default `uncertainty.lag_fraction`), the stated value clipped at 0;
- the halo (a job's `scatter`): the Gaussian with the halo's weight and
  second moment (sigma = sqrt(E[r^2]/2)) is taken as "true"; u = 5 % of the
  weight and 10 % of sigma (xgauge's defaults).  For a halo that is not
  Gaussian the Gaussian itself is an approximation whose error is not in u;
- a master's certificate (CMM): u drawn per run between 0.001 and 0.003 mm,
  the certified value the true one plus an error of that u.
"""

import numpy as np

CALIPER_U_MM = 0.01
LAG_REL_U = 0.1
HALO_WEIGHT_REL_U = 0.05
HALO_SIGMA_REL_U = 0.10


def caliper(true_dims, rng, u=CALIPER_U_MM):
    return {k: float(round(v + rng.normal(0.0, u), 5)) for k, v in true_dims.items()}


def lag(true_fraction, rng, rel_u=LAG_REL_U):
    u = rel_u * true_fraction
    return {"value": float(max(0.0, round(true_fraction + rng.normal(0.0, u), 7))), "u": float(round(u, 7)),
            "true": float(true_fraction)}


def halo(weight, sigma_mm, rng, rel_w=HALO_WEIGHT_REL_U, rel_s=HALO_SIGMA_REL_U):
    uw, us = rel_w * weight, rel_s * sigma_mm
    return {"weight": float(round(weight + rng.normal(0.0, uw), 6)),
            "sigma_mm": float(round(sigma_mm + rng.normal(0.0, us), 4)),
            "weight_uncertainty": float(round(uw, 6)), "sigma_uncertainty_mm": float(round(us, 4)),
            "true_weight": float(weight), "true_sigma_mm": float(sigma_mm)}


def certificate(true_dims, rng, lo=0.001, hi=0.003):
    u = float(round(rng.uniform(lo, hi), 5))
    return {k: {"value": float(round(v + rng.normal(0.0, u), 5)), "standard_uncertainty": u}
            for k, v in true_dims.items()}, u


def draw_session(seed, lag_true, halo_w, halo_sigma, wedge_dims):
    """All stated inputs of one run (one machine session)."""
    rng = np.random.default_rng([int(seed), 0x57A7ED])
    return {"caliper": {"values": caliper(wedge_dims, rng), "u_mm": CALIPER_U_MM, "true": dict(wedge_dims)},
            "lag_fraction": lag(lag_true, rng),
            "halo": halo(halo_w, halo_sigma, rng),
            "note": __doc__.strip()}
