// Detector lag (ghosting): a flat panel's scintillator and photodiodes carry
// a small fraction of one exposure's signal into the next. A radiograph then
// records
//
//   C = T + g P
//
// (flat-field corrected, before the white region's division), T the
// transmission of this shot, P the signal of the frame exposed just before
// (itself with its own lag, which is exactly what lags), g the lag fraction,
// typically 0.001 to 0.03 for the first frame after an exposure. Left in, it
// lays a faint copy of the previous shot's shadow over this one: with a part
// translated by 10 mm between shots, a lag of 0.003 moves the groove walls of
// the replica's Prism A by about 0.04 mm.
//
// The correction subtracts g P, with P the previous frame flat-field
// corrected by the same dark and flat frames. The fraction is the machine's
// (detector.lag_fraction) or, when the machine states none, estimated from
// the pair itself: where this shot sees open beam but the previous one had
// the part's edges, C - open level = g P, and a band-pass of both images
// (which removes the open level, the scatter's smooth halo and the heel)
// regresses one on the other. No library estimates a lag from a single
// pair of frames; this file is that estimate.
#pragma once

#include "xgauge/image/image.h"

#include <cstdint>
#include <string>

namespace xgauge {

struct LagEstimate {
  double fraction = 0.0;     // g
  double uncertainty = 0.0;  // its standard uncertainty (jackknife over tiles)
  int64_t pixels = 0;        // pixels the regression used: open beam near the previous edges
  int tiles = 0;             // tiles among which they fall
  // The previous frame's structure there, against its noise: the sum of
  // squares of its band-pass over those pixels divided by what noise alone
  // would give (1: nothing but noise).
  double structure = 0.0;
  // The machine's fraction, not an estimate: `uncertainty` is then the
  // machine's (Machine::lagFractionUncertainty()).
  bool stated = false;
};

// Estimates g from `current` and `previous`, both flat-field corrected (not
// divided by a white level) and of one size, binned 2 x 2 until at most
// 1024 px wide. `open_level` is the current image's open-beam value (its
// white region's mean); pixels below 0.95 of it, smoothed over 2 px, and
// everything within 16 binned px of them, are this shot's own shadow and
// are left out; of the rest, the pixels near the previous frame's edges
// carry the estimate. Throws Error (naming `name`) when the
// images differ in size or hold a non-finite value. When too few pixels or
// too little of the previous shot's structure is seen in the open beam, the
// estimate comes back with its (large) uncertainty: the caller decides.
LagEstimate estimateLag(const Image& current, const Image& previous, double open_level,
                        const std::string& name);

// "fraction F +- U (estimated over N pixels of open beam)", or
// "fraction F +- U (the machine's)" when stated.
std::string describeLag(const LagEstimate& lag);

// current -= fraction * previous, pixel by pixel (sizes must match).
void subtractLag(Image& current, const Image& previous, double fraction);

// The largest standard uncertainty of an estimated lag fraction that a
// measurement accepts: panels lag by 0.001 to 0.03, so an estimate looser
// than this tells nothing, and the machine must state the fraction. Below
// it the estimate's uncertainty enters the measurement's budget.
inline constexpr double kMaxLagUncertainty = 0.005;

}  // namespace xgauge
