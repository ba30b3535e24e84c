#pragma once

/// @file fsm.hpp
/// @brief Umbrella header for the libfsm runtime.

#include "fsm/error.hpp"
#include "fsm/force_model.hpp"
#include "fsm/heun_integrator.hpp"
#include "fsm/implicit_euler_integrator.hpp"
#include "fsm/improved_euler_integrator.hpp"
#include "fsm/integrator.hpp"
#include "fsm/lattice.hpp"
#include "fsm/material.hpp"
#include "fsm/model_file.hpp"
#include "fsm/simulation.hpp"
#include "fsm/skinning.hpp"
#include "fsm/sphere_model.hpp"
#include "fsm/stability.hpp"
#include "fsm/symplectic_euler_integrator.hpp"
#include "fsm/tetrahedral_mesh.hpp"
#include "fsm/tissue_model.hpp"
#include "fsm/triangle_mesh.hpp"
#include "fsm/types.hpp"
#include "fsm/version.hpp"
#include "fsm/voigt_link.hpp"
