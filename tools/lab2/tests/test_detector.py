"""Halo kernels, the detector chain's flat-field correction, TIFF files."""

import os
import struct
import zlib

import numpy as np
import pytest
from scipy import signal

from lab2 import detector as Dt
from lab2 import tiffio
from lab2.render import Geometry
from lab2.spectrum import Beam

HALOS = [
    {"shape": "gaussian", "weight": 0.14, "sigma_mm": 6.0},
    {"shape": "gauss_exp", "weight": 0.12, "sigma_mm": 4.0, "tail_fraction": 0.3, "tail_length_mm": 8.0},
    {"shape": "two_gauss", "weight": 0.2, "sigma1_mm": 3.0, "sigma2_mm": 9.0, "fraction2": 0.4},
]


@pytest.mark.parametrize("h", HALOS, ids=[h["shape"] for h in HALOS])
def test_halo_kernel_conserves_signal(h):
    halo = Dt.Halo(h["shape"], h["weight"], **{k: v for k, v in h.items() if k not in ("shape", "weight")})
    cell = 0.5
    # a panel with a dark object, padded with open beam by more than every kernel's radius
    pad = max(int(np.ceil(Dt.Halo.radius(k, s) / cell)) for k, s, _ in halo.components) + 2
    panel = np.ones((60, 80))
    panel[20:40, 25:50] = 0.2
    panel[5:10, 60:70] = 0.0
    field = np.pad(panel, pad, constant_values=1.0)
    # the halo over the whole padded field (full linear convolution keeps every photon)
    total = (1 - halo.weight) * field.sum()
    for kind, scale, frac in halo.components:
        K = Dt.Halo.discrete_kernel(kind, scale, cell, cell)
        total += halo.weight * frac * signal.fftconvolve(field, K, mode="full").sum()
    assert abs(total - field.sum()) / field.sum() < 1e-9


@pytest.mark.parametrize("h", HALOS, ids=[h["shape"] for h in HALOS])
def test_halo_of_uniform_open_beam_is_uniform_and_moments(h):
    halo = Dt.Halo(h["shape"], h["weight"], **{k: v for k, v in h.items() if k not in ("shape", "weight")})
    S = np.ones((50, 70))
    out = halo.apply(S, lambda pu, pv: np.ones(np.shape(pu)), 0.4, 0.4)
    assert np.max(np.abs(out - 1.0)) < 1e-9
    # second moments of the discrete kernels match the densities' (2 s^2, 6 l^2)
    for kind, scale, _ in halo.components:
        cell = scale / 32
        K = Dt.Halo.discrete_kernel(kind, scale, cell, cell)
        n = K.shape[0] // 2
        y, x = np.mgrid[-n:n + 1, -n:n + 1] * cell
        m2 = (K * (x * x + y * y)).sum()
        assert m2 == pytest.approx((2.0 if kind == "gauss" else 6.0) * scale * scale, rel=2e-3)


def test_halo_edge_response():
    """A dark rectangle (the left half of a small panel) in an open world: the
    Gaussian halo at a pixel is w (1 - P) inside and 1 - w P outside, P the
    kernel's mass over the rectangle (a product of erf differences)."""
    from math import erf, sqrt
    s, w, pitch = 5.0, 0.2, 0.25
    halo = Dt.Halo("gaussian", w, sigma_mm=s)
    S = np.ones((40, 400))
    S[:, :200] = 0.0
    out = halo.apply(S, lambda pu, pv: np.ones(np.shape(pu)), pitch, pitch)

    def mass(a, b, x):
        return 0.5 * (erf((b - x) / (sqrt(2) * s)) - erf((a - x) / (sqrt(2) * s)))
    for v in (0, 20, 39):
        for u in (0, 50, 150, 199, 200, 250, 399):
            x, y = (u + 0.5) * pitch, (v + 0.5) * pitch
            P = mass(0.0, 50.0, x) * mass(0.0, 10.0, y)
            expected = w * (1 - P) if u < 200 else 1 - w * P
            assert out[v, u] == pytest.approx(expected, abs=2e-5)


def small_detector(**over):
    g = Geometry(1000.0, 128, 128, 0.5, 0.5, 61.3, 66.2)
    p = {"halo": {"shape": "gaussian", "weight": 0.14, "sigma_mm": 15.0}, "photons_per_open_pixel": 20000.0,
         "lag_fraction": 0.0, "dead_fraction": 0.0, "hot_fraction": 0.0}
    p.update(over)
    return Dt.Detector(g, p, seed=7)


def series(det, T, n, name):
    frames, prev = [], None
    for k in range(n):
        raw, prev = det.acquire(np.random.default_rng([7, hash(name) % 1000, k]), T, prev if k else None)
        frames.append(raw.astype(float))
    return np.mean(frames, axis=0)


def test_flat_corrected_open_beam_is_one_within_noise():
    det = small_detector()
    n = 8
    dark = series(det, None, n, "dark")
    flat = series(det, Dt.OPEN, n, "flat")
    raw, _ = det.acquire(np.random.default_rng(123), Dt.OPEN)
    c = Dt.flat_correct(raw, dark, flat)
    # the noise model: quanta (1 - w)^2 N0 S gain^2 k^2 + read^2 + 1/12 per frame, flat averaged over n frames
    k = det.adu_per_quantum
    S = det.open
    B = k * det.gain * det.N0 * det.halo_of(S) * (1 + det.p["crosstalk"])
    var_img = (k * det.gain) ** 2 * (1 - det.halo.weight) ** 2 * det.N0 * S + det.p["read_noise_adu"] ** 2 + 1 / 12
    pred = np.sqrt(var_img * (1 + 1 / n)) / B
    se = pred.mean() / np.sqrt(c.size)
    assert abs(c.mean() - 1.0) < 4 * se
    z = (c - 1.0) / pred
    assert z.std() == pytest.approx(1.0, abs=0.04)


def test_normalized_open_beam_with_lag_crosstalk_and_bad_pixels():
    det = small_detector(lag_fraction=0.01, crosstalk=0.008, dead_fraction=2e-3, hot_fraction=1e-3)
    dark = series(det, None, 4, "dark")
    flat = series(det, Dt.OPEN, 4, "flat")
    raw, _ = det.acquire(np.random.default_rng(5), Dt.OPEN)
    bad = det.dead | det.hot
    norm = Dt.normalize(raw, dark, flat, [10, 10, 30, 30], bad)
    good = ~bad
    assert np.isfinite(norm).all()
    # the flats' own lag (a uniform factor) is divided out by the white region, whose own noise
    # (900 pixels) sets the tolerance
    sd = norm[good].std()
    assert abs(norm[good].mean() - 1.0) < 4 * sd * np.sqrt(1 / 900 + 1 / good.sum())


def test_lag_and_crosstalk_signals():
    det = small_detector(lag_fraction=0.01, read_noise_adu=0.0)
    mean_bright, Q = det.expected(Dt.OPEN)
    after, _ = det.expected(None, previous=Q)
    assert np.allclose(after - det.dark, 0.01 * (mean_bright - det.dark), rtol=1e-12, atol=1e-9)
    det = small_detector(crosstalk=0.01)
    T = np.ones((128, 128))
    T[:64, :64] = 0.0
    img, _ = det.expected(T)
    flat, _ = det.expected(Dt.OPEN)
    c = (img - det.dark) / (flat - det.dark)
    # the open rows below the plate: columns under it read lower (halo aside: compare next to the boundary)
    step = c[120, 60:63].mean() - c[120, 65:68].mean()
    assert -0.01 * 0.5 * 1.2 < step < -0.01 * 0.5 * 0.6


def test_determinism_for_a_seed():
    a = small_detector()
    b = small_detector()
    ra, _ = a.acquire(np.random.default_rng([1, 2]), Dt.OPEN)
    rb, _ = b.acquire(np.random.default_rng([1, 2]), Dt.OPEN)
    assert np.array_equal(ra, rb)
    c = Dt.Detector(a.geom, a.p, seed=8)
    rc, _ = c.acquire(np.random.default_rng([1, 2]), Dt.OPEN)
    assert not np.array_equal(ra, rc)


def test_tiff_round_trips(tmp_path):
    rng = np.random.default_rng(0)
    a = rng.integers(0, 65536, size=(37, 53), dtype=np.uint16)
    a[0, 0], a[-1, -1] = 0, 65535
    p = str(tmp_path / "a.tif")
    tiffio.write_u16(p, a)
    b = tiffio.read(p)
    assert b.dtype == np.uint16 and np.array_equal(a, b)
    f = rng.normal(size=(20, 30)).astype(np.float32)
    p = str(tmp_path / "f.tif")
    tiffio.write_f32(p, f)
    assert np.array_equal(tiffio.read(p), f)
    # the floating-point predictor (TIFF TN3) as xgauge writes float images
    p = str(tmp_path / "pred3.tif")
    _write_tn3(p, f)
    assert np.array_equal(tiffio.read(p), f)


def _write_tn3(path, img):
    """A minimal little-endian float32 TIFF, deflate, predictor 3, one strip."""
    h, w = img.shape
    be = img.astype(">f4").view(np.uint8).reshape(h, w, 4)
    planes = be.transpose(0, 2, 1).reshape(h, 4 * w).astype(np.int16)
    diff = np.concatenate([planes[:, :1], np.diff(planes, axis=1)], axis=1) % 256
    data = zlib.compress(diff.astype(np.uint8).tobytes())
    tags = [(256, 4, w), (257, 4, h), (258, 3, 32), (259, 3, 8), (262, 3, 1), (273, 4, 0), (277, 3, 1),
            (278, 4, h), (279, 4, len(data)), (317, 3, 3), (339, 3, 3)]
    ifd_off = 8
    data_off = ifd_off + 2 + 12 * len(tags) + 4
    out = bytearray(b"II*\x00" + struct.pack("<I", ifd_off) + struct.pack("<H", len(tags)))
    for tag, typ, val in tags:
        if tag == 273:
            val = data_off
        out += struct.pack("<HHI", tag, typ, 1) + (struct.pack("<HH", val, 0) if typ == 3 else struct.pack("<I", val))
    out += struct.pack("<I", 0) + data
    with open(path, "wb") as fh:
        fh.write(out)


def test_spectrum_transmission():
    b = Beam(150, [("Be", 1.848, 1.0), ("Al", 2.699, 1.0)], ("Al", 2.699, 0.5), ("CsI", 4.51, 0.6))
    x = np.array([0.0, 0.5, 1.0, 5.0, 10.0, 20.0])
    T = b.transmission(x)
    assert T[0] == pytest.approx(1.0, abs=1e-15)
    assert np.all(np.diff(T) < 0)
    mu = b.mu("Al", 2.699)
    assert T[3] == pytest.approx((b.weights * np.exp(-mu * 5.0)).sum(), rel=1e-14)
    # beam hardening: the effective attenuation falls with the path
    eff = -np.log(T[1:]) / x[1:]
    assert np.all(np.diff(eff) < 0)
    f = b.lut(max_mm=30.0)
    L = np.linspace(0, 30, 1001)
    assert np.max(np.abs(f(L) - b.transmission(L))) < 1e-7
    assert "KL3" in b.line_names
