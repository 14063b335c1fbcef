// Pose candidates (private to measure/; docs/method.md, "Pose candidates"):
// the distinct local minima a free or rotated radiograph's pose search
// found, best first, and the mirrored poses a part's silhouette admits,
// which the joint fit tries in turn when the search's best leads to a fit
// the acceptance rule refuses.
#pragma once

#include "stages.h"
#include "xgauge/measure/model.h"
#include "xgauge/measure/schedule.h"

#include <string>
#include <vector>

namespace xgauge {

struct PoseCandidate {
  std::vector<double> pose;  // the values of model.poseIndices(r), in that order
  double loss = 0.0;         // the search's loss after the local refinement
  std::string origin;        // for the logs and result.json: "search start 2", ...
};

// The pose values of radiograph r in theta, and theta with them replaced.
std::vector<double> poseValues(const ForwardModel& model, const std::vector<double>& theta, int r);
void setPose(const ForwardModel& model, std::vector<double>& theta, int r,
             const std::vector<double>& pose);

// The candidates with their near-duplicates dropped: a candidate whose
// rotation lies within `separation_deg` of an earlier one's is the same
// minimum. Order kept (the first is the search's best).
std::vector<PoseCandidate> distinctCandidates(const ForwardModel& model, int r,
                                              const std::vector<PoseCandidate>& candidates,
                                              double separation_deg);

// The poses that project (almost) like radiograph r's in theta: its part
// mirrored in each of the planes through its reference centre normal to a
// part axis, and the world mirrored in the plane through the centre normal
// to the beam (R' = M_z R S_k, the position kept). Under a parallel beam
// a part symmetric in such a plane casts exactly the same radiograph at
// both poses; the cone beam tells them apart only by a few per cent of
// magnification across the part, so a search can settle on the wrong one.
// Poses whose angles fall outside the bounds are left out; each of the
// others is refined by `local`, side by side (Runner::refineEach).
std::vector<PoseCandidate> mirroredCandidates(ForwardModel& model, const std::vector<double>& theta,
                                              int r, const StagePlan& local, Runner& runner);

}  // namespace xgauge
