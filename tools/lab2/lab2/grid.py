"""The machine grid: 13 set-ups spanning 1024 to 4096 pixels, 0.1 to 0.2 mm
pitch, 80 to 220 kV, prism magnification 1.5 to 4, halo widths 20 to 80 mm
and every halo shape, with every detector effect on."""

import copy

BE = lambda mm: ["Be", 1.848, mm]  # noqa: E731
AL = lambda mm: ["Al", 2.699, mm]  # noqa: E731
CU = lambda mm: ["Cu", 8.96, mm]  # noqa: E731
CARBON = lambda mm: ["C", 1.7, mm]  # noqa: E731
CSI = lambda mm: ["CsI", 4.51, mm]  # noqa: E731


def _m(id, seed, desc, cols, rows, pitch, sdd, pp, kv, filters, window, scint, M, halo, det, prism="A"):
    d = {
        "photons_per_open_pixel": 40000.0, "open_signal_adu": 36000.0, "read_noise_adu": 8.0,
        "dark_level_adu": 4000.0, "dark_pixel_sigma_adu": 12.0, "dark_column_sigma_adu": 20.0,
        "gain_smooth_rms": 0.003, "gain_smooth_min_wavelength_mm": 40.0, "gain_pixel_rms": 0.002,
        "heel_gradient": 0.05, "heel_direction_deg": 90.0, "cos3": True, "crosstalk": 0.005,
        "lag_fraction": 0.004, "dead_fraction": 2e-5, "hot_fraction": 1e-5, "hot_extra_adu": [8000.0, 30000.0],
    }
    d.update(det)
    d["halo"] = halo
    return {
        "id": id, "seed": seed, "description": desc,
        "geometry": {"sdd_mm": sdd, "columns": cols, "rows": rows, "pitch_mm": [pitch, pitch],
                     "principal_point_px": pp},
        "beam": {"tube_kv": kv, "filters": filters, "detector_window": window, "scintillator": scint,
                 "bin_kev": 0.5, "anode_self_um": 4.0},
        "detector": d,
        "frames": {"darks": 8, "flats": 8},
        "wedge": {"fill": 0.8},
        "prism": {"magnification": M, "shots": 3, "step_mm": 10.0, "dimensions": prism},
    }


G = lambda w, s: {"shape": "gaussian", "weight": w, "sigma_mm": s}  # noqa: E731
GE = lambda w, s, f, l: {"shape": "gauss_exp", "weight": w, "sigma_mm": s, "tail_fraction": f, "tail_length_mm": l}  # noqa: E731,E741
GG = lambda w, s1, s2, f: {"shape": "two_gauss", "weight": w, "sigma1_mm": s1, "sigma2_mm": s2, "fraction2": f}  # noqa: E731

MACHINES = [
    _m("m01", 1101, "1024^2 x 0.2 mm, 220 kV, Gaussian halo like the thesis's (0.139, 50 mm)",
       1024, 1024, 0.2, 1000.0, [512.0, 512.0], 220, [BE(1.0), AL(1.0)], AL(0.5), CSI(0.6), 2.0,
       G(0.139, 50.0), {}),
    _m("m02", 1102, "1024^2 x 0.15 mm, 160 kV, Gaussian halo with an exponential tail",
       1024, 1024, 0.15, 800.0, [498.7, 530.2], 160, [BE(0.8), AL(2.0)], CARBON(1.0), CSI(0.5), 1.5,
       GE(0.12, 30.0, 0.25, 80.0), {"lag_fraction": 0.002, "crosstalk": 0.003, "heel_gradient": -0.04,
                                    "photons_per_open_pixel": 30000.0, "dark_level_adu": 3000.0}, "B"),
    _m("m03", 1103, "1536^2 x 0.139 mm, 100 kV, two Gaussians (20 and 70 mm)",
       1536, 1536, 0.139, 1200.0, [781.5, 742.0], 100, [BE(1.0), AL(0.5)], AL(0.5), CSI(0.4), 2.5,
       GG(0.10, 20.0, 70.0, 0.35), {"lag_fraction": 0.006, "crosstalk": 0.006, "heel_direction_deg": 0.0,
                                    "heel_gradient": 0.06, "photons_per_open_pixel": 25000.0}),
    _m("m04", 1104, "2048^2 x 0.1 mm, 120 kV, Gaussian halo 35 mm",
       2048, 2048, 0.1, 1000.0, [1010.0, 1049.5], 120, [BE(1.0), AL(1.0)], AL(0.5), CSI(0.6), 3.0,
       G(0.16, 35.0), {"lag_fraction": 0.003, "crosstalk": 0.004, "heel_gradient": 0.03}),
    _m("m05", 1105, "2048^2 x 0.2 mm, 220 kV with copper, long exponential tail",
       2048, 2048, 0.2, 1500.0, [1024.0, 1024.0], 220, [BE(1.0), CU(0.25)], CARBON(1.0), CSI(0.7), 4.0,
       GE(0.15, 60.0, 0.3, 120.0), {"lag_fraction": 0.008, "crosstalk": 0.007, "heel_gradient": 0.08,
                                    "heel_direction_deg": 270.0, "photons_per_open_pixel": 60000.0,
                                    "dark_level_adu": 5000.0}, "B"),
    _m("m06", 1106, "1024^2 x 0.2 mm, 80 kV, two Gaussians (25 and 80 mm)",
       1024, 1024, 0.2, 900.0, [530.0, 495.0], 80, [BE(0.5)], AL(0.3), CSI(0.5), 2.5,
       GG(0.12, 25.0, 80.0, 0.5), {"lag_fraction": 0.01, "crosstalk": 0.002, "heel_gradient": 0.02,
                                   "photons_per_open_pixel": 20000.0, "read_noise_adu": 12.0}),
    _m("m07", 1107, "2048^2 x 0.15 mm, 180 kV, wide Gaussian halo 80 mm",
       2048, 2048, 0.15, 1300.0, [1000.0, 1100.0], 180, [BE(1.0), AL(2.0)], AL(0.5), CSI(0.6), 3.5,
       G(0.18, 80.0), {"lag_fraction": 0.005, "crosstalk": 0.008, "heel_direction_deg": 180.0,
                       "heel_gradient": 0.05}, "B"),
    _m("m08", 1108, "1280 x 1024 x 0.2 mm, 140 kV, narrow Gaussian with a tail, principal point off centre",
       1280, 1024, 0.2, 1000.0, [600.0, 540.0], 140, [BE(1.0), AL(1.0)], CARBON(0.8), CSI(0.5), 2.0,
       GE(0.09, 20.0, 0.2, 50.0), {"lag_fraction": 0.001, "crosstalk": 0.005, "heel_direction_deg": 45.0,
                                   "heel_gradient": 0.04, "dead_fraction": 5e-5, "hot_fraction": 3e-5}),
    _m("m09", 1109, "2048^2 x 0.127 mm, 200 kV, two Gaussians (40 and 75 mm), strong halo",
       2048, 2048, 0.127, 1100.0, [1030.0, 1010.0], 200, [BE(1.0), AL(1.5)], AL(0.5), CSI(0.6), 2.2,
       GG(0.20, 40.0, 75.0, 0.3), {"lag_fraction": 0.004, "crosstalk": 0.005, "heel_gradient": -0.05}),
    _m("m10", 1110, "1536^2 x 0.2 mm, 90 kV, narrow Gaussian 20 mm, magnification 4",
       1536, 1536, 0.2, 1000.0, [768.0, 768.0], 90, [BE(1.0), AL(0.5)], AL(0.5), CSI(0.4), 4.0,
       G(0.08, 20.0), {"lag_fraction": 0.007, "crosstalk": 0.003, "photons_per_open_pixel": 35000.0}),
    _m("m11", 1111, "4096^2 x 0.1 mm, 220 kV, the thesis's cabinet and halo (0.139, 50 mm)",
       4096, 4096, 0.1, 1000.0, [2048.0, 2048.0], 220, [BE(1.0), AL(1.0)], AL(0.5), CSI(0.6), 3.0,
       G(0.139, 50.0), {"lag_fraction": 0.003, "crosstalk": 0.005, "heel_gradient": 0.03}),
    _m("m12", 1112, "2048^2 x 0.1 mm, 150 kV, Gaussian 40 mm with a heavy 100 mm tail, magnification 1.5",
       2048, 2048, 0.1, 1000.0, [1024.0, 990.0], 150, [BE(1.0), AL(1.0), CU(0.1)], CARBON(1.0), CSI(0.6), 1.5,
       GE(0.14, 40.0, 0.4, 100.0), {"lag_fraction": 0.005, "crosstalk": 0.006, "heel_direction_deg": 135.0,
                                    "heel_gradient": 0.06}),
    _m("m13", 1113, "1024 x 1280 (portrait) x 0.16 mm, 130 kV, two Gaussians (30 and 60 mm)",
       1024, 1280, 0.16, 1000.0, [520.0, 650.0], 130, [BE(1.0), AL(1.0)], AL(0.5), CSI(0.5), 2.8,
       GG(0.11, 30.0, 60.0, 0.2), {"lag_fraction": 0.002, "crosstalk": 0.004, "heel_gradient": 0.03,
                                   "heel_direction_deg": 300.0}, "B"),
]


def machine(id):
    for m in MACHINES:
        if m["id"] == id:
            return copy.deepcopy(m)
    raise KeyError(f"unknown machine {id!r} (known: {', '.join(m['id'] for m in MACHINES)})")

# The measured-parts suite (lab2.py suite): the small panels, one per halo shape, so that a whole run stays
# within about half an hour on two cores.
SUITE = ["m01", "m02", "m06", "m08"]
