#pragma once

// fsm-demo --scenario myomectomy: incise around the fibroid, grasp it and pull until it is free,
// through the 1 kHz servo loop (docs/demo.md, "The myomectomy scenario").

#include <string>

#include "fsm/haptics/servo_loop.hpp"
#include "fsm/tissue_model.hpp"

namespace fsm::examples {

struct ScenarioOptions {
  std::string out;           ///< where the renders, the force plot and stats.json go
  bool json{false};          ///< print the statistics as JSON
  bool render{true};         ///< write the PNG renders
  int stress{0};             ///< competing busy processes during the session
  int realtime{0};           ///< SCHED_FIFO priority of the loop's threads; 0: none
  double capsule_tear{0.2};  ///< tear strain of the fibroid's attachment (the capsule)
  std::string law{"scene"};  ///< the tetrahedral parts' force law: scene, links or continuum
};

/// Sets every tetrahedral part's force law in `spheres` (a copy of model.spheres): "links" or
/// "continuum"; "scene" leaves each part's own. Returns the law the tetrahedral parts then use:
/// "links", "continuum" or "mixed" (the demo's --law, reported in stats.json).
std::string apply_law(const TissueModel<double>& model, SphereModel<double>& spheres,
                      const std::string& law);

/// The session's energy gain as JSON fields (no braces): `"energy_gain_retries": N,
/// "largest_energy_gain_J": X, "largest_energy_gain_to_limit": Y` (null where not known; `limit`:
/// Simulation::energy_gain_limit(), 0 when off).
std::string energy_gain_json(const haptics::ServoStats& stats, double limit);

/// Runs the scenario on `model` (it needs parts named "body" and "fibroid"; fsm::Error if not).
/// Returns the process's exit status.
int run_myomectomy(const TissueModel<double>& model, const ScenarioOptions& options);

}  // namespace fsm::examples
