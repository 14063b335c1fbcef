"""A polychromatic tungsten-tube beam and an energy-integrating CsI detector.

Model (lab2's own; every attenuation coefficient from xraylib):

- Bremsstrahlung: Kramers' law, photons per keV  n(E) ~ (E0 - E) / E  for
  E < E0 = tube voltage, in bins of ``bin_kev`` from ``e_min_kev``.
- Anode self-absorption: an effective tungsten layer (``anode_self_um``, a
  few micrometres) in the beam; the depth distribution of the electrons in
  the target and the take-off angle are not modelled.
- Characteristic lines of tungsten, at xraylib's line energies, weighted
  within each shell by xraylib's radiative rates: the K lines (KL3, KL2,
  KM3, KM2, KN3) when E0 exceeds the K edge, the L3/L2 lines (LA1, LA2,
  LB1, LB2, LG1) when E0 exceeds the L3 edge.  Their total photon number per
  shell is a rough empirical law, N = k (U - 1)^1.63 n(E_line) x 1 keV, with
  U = E0 / E_edge and k = ``k_line_scale`` (2.5 for K) or ``l_line_scale``;
  not fitted to measured spectra.  The L lines never pass the filters.
- Filters: the tube window and added filters, then (at the detector) its
  entrance window: narrow-beam transmission exp(-mu t), mu from xraylib's
  total cross section (photo-absorption + coherent + incoherent).
- Scintillator: energy-integrating; a photon of energy E deposits on
  average E (1 - exp(-mu t)) mu_en / mu, with mu_en xraylib's mass
  energy-absorption coefficient (fluorescence escape and Compton energy
  that leaves the layer are in mu_en only on average).  The optical gain
  per deposited keV is taken as constant.

Not modelled: the focal spot's size and its spectrum's dependence on the
emission angle (the heel effect is a detector-side intensity slope, see
detector.py), scatter in the part and in the air (all paths are
narrow-beam), the scintillator's Swank noise (the noise model uses
noise-equivalent quanta).
"""

import numpy as np
import xraylib

W_Z = 74


def mu_per_mm(compound, density_g_cm3, energies_kev):
    """Linear attenuation coefficient (1/mm), total cross section."""
    E = np.atleast_1d(np.asarray(energies_kev, float))
    cs = np.array([_cs(compound, e, xraylib.CS_Total_CP) for e in E])
    return cs * density_g_cm3 / 10.0


def mu_en_per_mm(compound, density_g_cm3, energies_kev):
    E = np.atleast_1d(np.asarray(energies_kev, float))
    cs = np.array([_cs(compound, e, xraylib.CS_Energy_CP) for e in E])
    return cs * density_g_cm3 / 10.0


def _cs(compound, e, fn):
    try:
        return fn(compound, float(e))
    except ValueError:
        # a NIST compound name rather than a formula
        data = xraylib.GetCompoundDataNISTByName(compound)
        return sum(w * fn(xraylib.AtomicNumberToSymbol(z), float(e))
                   for z, w in zip(data["Elements"], data["massFractions"]))


K_LINES = ("KL3_LINE", "KL2_LINE", "KM3_LINE", "KM2_LINE", "KN3_LINE")
L_LINES = ("LA1_LINE", "LA2_LINE", "LB1_LINE", "LB2_LINE", "LG1_LINE")


class Beam:
    """The beam as the detector records it.

    filters: [(compound, density, thickness_mm)] between focal spot and part
    (tube window first); detector_window and scintillator likewise, at the
    detector.
    """

    def __init__(self, tube_kv, filters, detector_window, scintillator,
                 bin_kev=0.5, e_min_kev=5.0, anode_self_um=4.0, k_line_scale=2.5, l_line_scale=1.0):
        self.tube_kv = float(tube_kv)
        self.filters = [tuple(f) for f in filters]
        self.detector_window = tuple(detector_window)
        self.scintillator = tuple(scintillator)
        self.bin_kev = float(bin_kev)
        self.e_min_kev = float(e_min_kev)
        self.anode_self_um = float(anode_self_um)
        self.k_line_scale = float(k_line_scale)
        self.l_line_scale = float(l_line_scale)
        E0 = self.tube_kv
        edges = np.arange(self.e_min_kev, E0 + 1e-9, self.bin_kev)
        if edges[-1] < E0:
            edges = np.append(edges, E0)
        Ec = 0.5 * (edges[1:] + edges[:-1])
        nc = (E0 - Ec) / Ec * np.diff(edges)
        kramers = lambda e: max(E0 - e, 0.0) / e  # noqa: E731
        lines_E, lines_n, lines_name = [], [], []
        for shell, edge_id, names, scale in ((xraylib.K_SHELL, None, K_LINES, self.k_line_scale),
                                             (xraylib.L3_SHELL, None, L_LINES, self.l_line_scale)):
            edge = xraylib.EdgeEnergy(W_Z, shell)
            if E0 <= edge:
                continue
            U = E0 / edge
            energies = [xraylib.LineEnergy(W_Z, getattr(xraylib, n)) for n in names]
            rates = np.array([xraylib.RadRate(W_Z, getattr(xraylib, n)) for n in names])
            rates = rates / rates.sum()
            total = scale * (U - 1.0) ** 1.63 * kramers(energies[0]) * 1.0
            for n, e, r in zip(names, energies, rates):
                if e >= self.e_min_kev:
                    lines_E.append(e)
                    lines_n.append(total * r)
                    lines_name.append(n.replace("_LINE", ""))
        self.energies = np.concatenate([Ec, lines_E])
        self.emitted = np.concatenate([nc, lines_n])
        self.line_names = lines_name
        E = self.energies
        t = np.exp(-mu_per_mm("W", 19.3, E) * self.anode_self_um * 1e-3)
        for comp, rho, mm in self.filters:
            t = t * np.exp(-mu_per_mm(comp, rho, E) * mm)
        self.incident = self.emitted * t  # photons reaching the part, per bin
        comp, rho, mm = self.detector_window
        win = np.exp(-mu_per_mm(comp, rho, E) * mm)
        comp, rho, mm = self.scintillator
        mu_s = mu_per_mm(comp, rho, E)
        mu_en = mu_en_per_mm(comp, rho, E)
        self.absorbed_fraction = 1.0 - np.exp(-mu_s * mm)
        self.deposit_per_photon = E * self.absorbed_fraction * np.minimum(mu_en / mu_s, 1.0)
        signal = self.incident * win * self.deposit_per_photon
        self.weights = signal / signal.sum()
        self.photon_weights = self.incident * win * self.absorbed_fraction
        self.photon_weights = self.photon_weights / self.photon_weights.sum()
        self._mu_cache = {}

    def mu(self, compound, density):
        key = (compound, float(density))
        if key not in self._mu_cache:
            self._mu_cache[key] = mu_per_mm(compound, density, self.energies)
        return self._mu_cache[key]

    def transmission(self, path_mm, compound="Al", density=2.699):
        """Energy-integrated signal behind path_mm of material, open beam = 1."""
        L = np.atleast_1d(np.asarray(path_mm, float))
        mu = self.mu(compound, density)
        out = np.empty(L.shape)
        flat = L.ravel()
        res = out.ravel()
        for a in range(0, len(flat), 4096):
            res[a:a + 4096] = np.exp(-np.outer(flat[a:a + 4096], mu)) @ self.weights
        return out

    def lut(self, compound="Al", density=2.699, max_mm=200.0, step_mm=5e-4):
        """A fast T(L) by linear interpolation on a fine table (the error of
        the interpolation is below 1e-7 for aluminium beyond 20 keV)."""
        x = np.arange(0.0, max_mm + step_mm, step_mm)
        y = self.transmission(x, compound, density)

        def f(L):
            L = np.asarray(L, float)
            if L.size and L.max() > x[-1]:
                raise ValueError(f"path {L.max():.3f} mm beyond the table ({x[-1]} mm)")
            return np.interp(L, x, y)
        return f

    def mean_energy(self):
        return float((self.weights * self.energies).sum())

    def summary(self):
        return {
            "model": "Kramers continuum + tungsten K/L lines (xraylib energies and radiative rates), "
                     "narrow-beam filters, energy-integrating CsI (E (1 - exp(-mu t)) mu_en/mu)",
            "tube_kv": self.tube_kv, "bin_kev": self.bin_kev, "e_min_kev": self.e_min_kev,
            "anode_self_filtration_w_um": self.anode_self_um,
            "k_line_scale": self.k_line_scale, "l_line_scale": self.l_line_scale,
            "lines": self.line_names,
            "mean_detected_energy_kev": self.mean_energy(),
            "k_line_share_of_signal": float(self.weights[len(self.weights) - len(self.line_names):].sum())
            if self.line_names else 0.0,
        }
