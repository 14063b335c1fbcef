"""The flat-panel detector: open-beam field, scintillator halo, gain,
lag, column crosstalk, bad pixels, noise, dark offsets, 16-bit read-out.

Order of the physics in one frame (acquire()):

1. incident signal  S = O * T: the transmission T of the scene times the
   open-beam field O = heel * cos^3 (the heel effect is a linear slope of
   the tube's output across the panel, along a direction of the machine's;
   cos^3 of the ray's angle to the detector normal is the inverse square
   and the obliquity of the pixel seen from the focal spot).  Both belong
   to the X-ray field, so they come before the scintillator.
2. X-ray quanta absorbed: Poisson(N0 * S), N0 the noise-equivalent quanta
   of an open pixel at the principal point.
3. scintillator halo (light spread): L = (1 - w) S + w K * S, K a
   normalised radial kernel (Gaussian; Gaussian plus exponential tail; two
   Gaussians), computed on the incident signal with the world beyond the
   panel taken as open beam (O continued analytically).  The quantum noise
   keeps its local part, (1 - w) (N - N0 S); the part the kernel spreads
   over thousands of pixels (relative variance w^2 sum K^2, below 1e-6) is
   not added.
4. pixel gain: a smooth pattern (sum of random cosines, rms ~0.3 %) times a
   per-pixel spread; dead pixels have gain 0.
5. lag: the frame also releases a fraction g of the previous frame's signal
   (its own lag included): R_k = Q_k + g R_{k-1}; a "rest" clears it.
6. column crosstalk: every pixel of a column picks up c times the mean
   signal of that column (charge coupled onto the data line), so a flat
   field corrects the open beam exactly but a column crossing a dark object
   reads lower by about c times its mean attenuation.
7. read-out: ADU = dark (level + per-pixel + per-column fixed offsets) +
   gain_adu * X + Gaussian read noise; hot pixels add a large fixed dark
   current; rounded and clamped to 0..65535.
"""

import math

import numpy as np
from scipy import ndimage, signal

HALO_SHAPES = ("gaussian", "gauss_exp", "two_gauss")


class Halo:
    """I' = (1 - w) I + w K * I with K = sum_c f_c K_c, each K_c a normalised
    radial density in mm: Gaussian exp(-r^2 / 2 s^2) / (2 pi s^2) or
    exponential exp(-r / l) / (2 pi l^2)."""

    def __init__(self, shape, weight, **p):
        self.shape = shape
        self.weight = float(weight)
        self.params = dict(p)
        if shape == "gaussian":
            self.components = [("gauss", float(p["sigma_mm"]), 1.0)]
        elif shape == "gauss_exp":
            f = float(p["tail_fraction"])
            self.components = [("gauss", float(p["sigma_mm"]), 1.0 - f), ("exp", float(p["tail_length_mm"]), f)]
        elif shape == "two_gauss":
            f = float(p["fraction2"])
            self.components = [("gauss", float(p["sigma1_mm"]), 1.0 - f), ("gauss", float(p["sigma2_mm"]), f)]
        else:
            raise ValueError(f"unknown halo shape {shape!r} (known: {', '.join(HALO_SHAPES)})")

    def truth(self):
        mean_r2 = sum(f * (2 * s * s if k == "gauss" else 6 * s * s) for k, s, f in self.components)
        return {"shape": self.shape, "weight": self.weight, **self.params,
                "components": [{"kind": k, "scale_mm": s, "fraction": f} for k, s, f in self.components],
                "formula": "I' = (1 - weight) I + weight sum_c fraction_c K_c * I; gauss K = exp(-r^2/(2 s^2))/(2 pi s^2), "
                           "exp K = exp(-r/s)/(2 pi s^2), r in mm on the detector",
                "gaussian_equivalent_sigma_mm": math.sqrt(mean_r2 / 2.0)}

    @staticmethod
    def density(kind, scale, r):
        if kind == "gauss":
            return np.exp(-0.5 * (r / scale) ** 2) / (2 * np.pi * scale * scale)
        return np.exp(-r / scale) / (2 * np.pi * scale * scale)

    @staticmethod
    def radius(kind, scale):
        # mass outside: gauss exp(-R^2/2s^2) = 2.7e-7 at 5.5 s; exp (1 + R/l) e^{-R/l} = 7.8e-7 at 17 l
        return 5.5 * scale if kind == "gauss" else 17.0 * scale

    @staticmethod
    def discrete_kernel(kind, scale, cell_u, cell_v, radius=None):
        """The kernel on a grid of cells (cell_u x cell_v mm), odd size,
        centred, normalised to sum 1 (so a convolution conserves the signal)."""
        R = Halo.radius(kind, scale) if radius is None else radius
        nu, nv = int(math.ceil(R / cell_u)), int(math.ceil(R / cell_v))
        y, x = np.mgrid[-nv:nv + 1, -nu:nu + 1]
        r = np.hypot(x * cell_u, y * cell_v)
        if kind == "exp":
            # the cusp at r = 0: average the central cell over 8 x 8 points
            k = Halo.density(kind, scale, r)
            s = (np.arange(8) + 0.5) / 8 - 0.5
            su, sv = np.meshgrid(s * cell_u, s * cell_v)
            k[nv, nu] = Halo.density(kind, scale, np.hypot(su, sv)).mean()
        else:
            k = Halo.density(kind, scale, r)
        k[r > R] = 0.0
        return k / k.sum()

    def apply(self, S, open_field, pitch_u, pitch_v, cells_per_scale=32):
        """The halo of the panel image S (rows x columns), the world beyond
        the panel being open_field(pu, pv) (continuous pixel coordinates)."""
        out = (1.0 - self.weight) * S
        for kind, scale, frac in self.components:
            out += self.weight * frac * blur_padded(S, open_field, kind, scale, pitch_u, pitch_v, cells_per_scale)
        return out


def blur_padded(S, open_field, kind, scale, pitch_u, pitch_v, cells_per_scale=32):
    """K * S on the panel, the panel padded with the open field beyond its
    edges.  Computed on cells of b x b pixels (b = scale / pitch / 32,
    at least 1): the panel is averaged over each cell, the padded cell image
    convolved (FFT, linear, the padding at least the kernel's radius so the
    panel's result is the full convolution), then interpolated bilinearly
    back to the pixels.  With 32 cells per sigma (or per tail length) the
    cells add 1/(12 x 32^2) of sigma^2 to the kernel's variance and the
    interpolation errs by about 1e-5 of the halo's amplitude."""
    R, C = S.shape
    bu = max(1, int(scale / pitch_u / cells_per_scale))
    bv = max(1, int(scale / pitch_v / cells_per_scale))
    cu, cv = bu * pitch_u, bv * pitch_v
    K = Halo.discrete_kernel(kind, scale, cu, cv)
    ku, kv = K.shape[1] // 2, K.shape[0] // 2
    nu, nv = -(-C // bu), -(-R // bv)
    Pu, Pv = ku + 2, kv + 2
    # coarse panel: cell means, the part of a cell beyond the panel filled with open beam
    full = np.empty((nv * bv, nu * bu))
    full[:R, :C] = S
    if nv * bv > R or nu * bu > C:
        vv, uu = np.mgrid[0:nv * bv, 0:nu * bu]
        outside = (vv >= R) | (uu >= C)
        full[outside] = open_field(uu[outside] + 0.5, vv[outside] + 0.5)
    coarse = full.reshape(nv, bv, nu, bu).mean(axis=(1, 3))
    iv, iu = np.mgrid[-Pv:nv + Pv, -Pu:nu + Pu]
    padded = open_field((iu + 0.5) * bu, (iv + 0.5) * bv)
    padded[Pv:Pv + nv, Pu:Pu + nu] = coarse
    conv = signal.fftconvolve(padded, K, mode="same")
    # back to pixel centres: cell i (padded index) has its centre at pixel coordinate (i - P + 1/2) b
    fv = (np.arange(R) + 0.5) / bv - 0.5 + Pv
    fu = (np.arange(C) + 0.5) / bu - 0.5 + Pu
    return _interp_axis(_interp_axis(conv, fv, 0), fu, 1)


def _interp_axis(a, x, axis):
    i0 = np.clip(np.floor(x).astype(int), 0, a.shape[axis] - 2)
    f = x - i0
    a0 = np.take(a, i0, axis=axis)
    a1 = np.take(a, i0 + 1, axis=axis)
    shape = [1, 1]
    shape[axis] = -1
    f = f.reshape(shape)
    return a0 * (1 - f) + a1 * f


class Detector:
    """A flat panel with every effect of the module's description.

    geom: render.Geometry; p: dict of parameters (see DEFAULTS)."""

    DEFAULTS = {
        "photons_per_open_pixel": 40000.0,   # noise-equivalent quanta N0
        "open_signal_adu": 36000.0,          # ADU above dark for N0 quanta at gain 1
        "read_noise_adu": 8.0,
        "dark_level_adu": 4000.0,
        "dark_pixel_sigma_adu": 12.0,
        "dark_column_sigma_adu": 20.0,
        "gain_smooth_rms": 0.003,
        "gain_smooth_min_wavelength_mm": 40.0,
        "gain_pixel_rms": 0.002,
        "heel_gradient": 0.05,               # relative change across the panel
        "heel_direction_deg": 90.0,          # 0: along +u (columns grow), 90: along +v (rows grow)
        "cos3": True,
        "crosstalk": 0.005,
        "lag_fraction": 0.004,
        "dead_fraction": 2e-5,
        "hot_fraction": 1e-5,
        "hot_extra_adu": [8000.0, 30000.0],
        "halo": {"shape": "gaussian", "weight": 0.14, "sigma_mm": 50.0},
    }

    def __init__(self, geom, params=None, seed=0):
        self.geom = geom
        p = dict(self.DEFAULTS)
        p.update(params or {})
        self.p = p
        self.seed = int(seed)
        h = p["halo"]
        self.halo = Halo(h["shape"], h["weight"], **{k: v for k, v in h.items() if k not in ("shape", "weight")})
        self.N0 = float(p["photons_per_open_pixel"])
        self.adu_per_quantum = float(p["open_signal_adu"]) / self.N0
        R, C = geom.rows, geom.columns
        rng = np.random.default_rng([self.seed, 0xF1ED])
        # fixed patterns
        vv, uu = np.mgrid[0:R, 0:C]
        self.open = self.open_field(uu + 0.5, vv + 0.5)
        self.gain = self._smooth_gain(rng) * (1.0 + p["gain_pixel_rms"] * rng.standard_normal((R, C)))
        n = R * C
        n_dead = int(round(p["dead_fraction"] * n))
        n_hot = int(round(p["hot_fraction"] * n))
        idx = rng.choice(n, n_dead + n_hot, replace=False)
        self.dead = np.zeros((R, C), bool)
        self.hot = np.zeros((R, C), bool)
        self.dead.flat[idx[:n_dead]] = True
        self.hot.flat[idx[n_dead:]] = True
        self.gain[self.dead] = 0.0
        self.dark = (p["dark_level_adu"] + p["dark_pixel_sigma_adu"] * rng.standard_normal((R, C))
                     + p["dark_column_sigma_adu"] * rng.standard_normal(C)[None, :])
        lo, hi = p["hot_extra_adu"]
        self.dark[self.hot] += rng.uniform(lo, hi, n_hot)
        self._open_halo = None

    # -- the X-ray field --------------------------------------------------
    def open_field(self, pu, pv):
        g = self.geom
        x = (np.asarray(pu, float) - g.cx) * g.pitch_u
        y = (np.asarray(pv, float) - g.cy) * g.pitch_v  # along +v (rows), mm
        phi = math.radians(self.p["heel_direction_deg"])
        size = max(g.columns * g.pitch_u, g.rows * g.pitch_v)
        heel = np.maximum(1.0 + self.p["heel_gradient"] * (x * math.cos(phi) + y * math.sin(phi)) / size, 0.0)
        if self.p["cos3"]:
            D = g.sdd
            heel = heel * (D / np.sqrt(D * D + x * x + y * y)) ** 3
        return heel

    def _smooth_gain(self, rng):
        g = self.geom
        R, C = g.rows, g.columns
        y = (np.arange(R) + 0.5) * g.pitch_v
        x = (np.arange(C) + 0.5) * g.pitch_u
        field = np.zeros((R, C))
        lam_min = self.p["gain_smooth_min_wavelength_mm"]
        for _ in range(12):
            lam = lam_min * math.exp(rng.uniform(0, math.log(8.0)))
            th = rng.uniform(0, 2 * math.pi)
            ph = rng.uniform(0, 2 * math.pi)
            kx, ky = 2 * math.pi / lam * math.cos(th), 2 * math.pi / lam * math.sin(th)
            # separable: cos(kx x + ky y + ph) = cos(a)cos(b) - sin(a)sin(b)
            a, b = kx * x + ph, ky * y
            field += np.outer(np.cos(b), np.cos(a)) - np.outer(np.sin(b), np.sin(a))
        field *= self.p["gain_smooth_rms"] / field.std()
        return 1.0 + field

    def halo_of(self, S):
        g = self.geom
        return self.halo.apply(S, self.open_field, g.pitch_u, g.pitch_v)

    # -- one frame --------------------------------------------------------
    def acquire(self, rng, T=None, previous=None):
        """One raw frame.  T: the scene's transmission image (None: beam
        off).  previous: the signal the previous frame returned (None after
        a rest).  Returns (raw uint16, signal for the next frame's lag)."""
        R, C = self.geom.rows, self.geom.columns
        if T is None:
            light = np.zeros((R, C))
        else:
            if isinstance(T, str) and T == OPEN:
                S = self.open
                if self._open_halo is None:
                    self._open_halo = self.halo_of(self.open)
                mean_light = self._open_halo
            else:
                S = self.open * T
                mean_light = self.halo_of(S)
            lam = self.N0 * S
            quanta = rng.poisson(lam).astype(float)
            light = self.N0 * mean_light + (1.0 - self.halo.weight) * (quanta - lam)
        Q = self.gain * light
        if previous is not None:
            Q = Q + self.p["lag_fraction"] * previous
        X = Q + self.p["crosstalk"] * Q.mean(axis=0)[None, :]
        adu = self.dark + X * self.adu_per_quantum + self.p["read_noise_adu"] * rng.standard_normal((R, C))
        raw = np.clip(np.rint(adu), 0, 65535).astype(np.uint16)
        return raw, Q

    def expected(self, T=None, previous=None):
        """The noise-free mean of acquire() before read-out rounding (ADU)."""
        R, C = self.geom.rows, self.geom.columns
        if T is None:
            light = np.zeros((R, C))
        else:
            light = self.N0 * self.halo_of(self.open if isinstance(T, str) else self.open * T)
        Q = self.gain * light
        if previous is not None:
            Q = Q + self.p["lag_fraction"] * previous
        X = Q + self.p["crosstalk"] * Q.mean(axis=0)[None, :]
        return self.dark + X * self.adu_per_quantum, Q

    def truth(self):
        p = self.p
        return {
            "halo": self.halo.truth(),
            "lag_fraction": p["lag_fraction"],
            "lag_model": "R_k = Q_k + lag_fraction R_(k-1), Q the frame's own signal, R_(k-1) the previous frame's "
                         "(its own lag included); a rest before a frame clears it",
            "crosstalk": p["crosstalk"],
            "crosstalk_model": "X(u, v) = R(u, v) + crosstalk * mean over rows of R(u, .)",
            "heel_gradient": p["heel_gradient"], "heel_direction_deg": p["heel_direction_deg"],
            "heel_model": "1 + heel_gradient * (x cos(dir) + y_down sin(dir)) / max(panel width, height); x, y_down "
                          "in mm from the principal point, y_down along +v",
            "cos3": p["cos3"],
            "gain_smooth_rms": p["gain_smooth_rms"], "gain_pixel_rms": p["gain_pixel_rms"],
            "photons_per_open_pixel": self.N0, "adu_per_quantum": self.adu_per_quantum,
            "read_noise_adu": p["read_noise_adu"], "dark_level_adu": p["dark_level_adu"],
            "dark_pixel_sigma_adu": p["dark_pixel_sigma_adu"], "dark_column_sigma_adu": p["dark_column_sigma_adu"],
            "dead_pixels": [[int(u), int(v)] for v, u in zip(*np.nonzero(self.dead))],
            "hot_pixels": [[int(u), int(v)] for v, u in zip(*np.nonzero(self.hot))],
        }


OPEN = "open"  # acquire(T=OPEN): the open beam (T = 1), whose halo is cached


def bad_pixel_mask(dark, flat, extra=None):
    bad = ~(flat > dark)
    if extra is not None:
        bad |= extra
    return bad


def repair(img, bad):
    """Replace bad pixels by the mean of their good 8-neighbours (repeated
    until none is left without one)."""
    out = img.astype(np.float64).copy()
    bad = bad.copy()
    k = np.ones((3, 3))
    for _ in range(16):
        if not bad.any():
            break
        good = ~bad
        s = ndimage.convolve(np.where(good, out, 0.0), k, mode="nearest")
        n = ndimage.convolve(good.astype(float), k, mode="nearest")
        fix = bad & (n > 0)
        out[fix] = s[fix] / n[fix]
        bad &= ~fix
    return out


def flat_correct(raw, dark, flat, bad=None):
    """(raw - dark) / (flat - dark), bad pixels (flat <= dark, or listed)
    repaired from their neighbours."""
    den = flat.astype(float) - dark
    mask = bad_pixel_mask(dark, flat, bad)
    with np.errstate(divide="ignore", invalid="ignore"):
        c = (raw.astype(float) - dark) / np.where(mask, 1.0, den)
    return repair(c, mask)


def normalize(raw, dark, flat, white_region, bad=None):
    c = flat_correct(raw, dark, flat, bad)
    x, y, w, h = white_region
    return c / c[y:y + h, x:x + w].mean()
