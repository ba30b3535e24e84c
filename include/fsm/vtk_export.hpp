#pragma once
/// @file vtk_export.hpp
/// @brief Simulation states as a ParaView time series (VTK XML `.vtu` pieces and a `.pvd` index).
///
/// Outside the real-time step (it writes files and allocates). Each write() stores one state:
/// - `NAME_spheres_NNNNNN.vtu`: the spheres as points with point data `radius` (m), `velocity`
///   (m/s), `force` (N), `fixed` and `region`; the links as VTK_LINE cells and the
///   tetrahedra of tetrahedral parts (SphereModel::tetrahedra()) as VTK_TETRA cells, with cell data
///   `kind` (0 link, 1 tetrahedron);
/// - `NAME_surface_NNNNNN.vtu` (with a skin): the render surface as triangles, cell data `surface`
///   (the index of the part's surface in Skin::surfaces);
/// - `NAME.pvd`, rewritten after every state: the series, spheres as part 0 and the surface as
///   part 1, each at its time (s), so a run stopped early still opens in ParaView.
/// The arrays are inline base64 binary, little-endian, with UInt64 headers (VTK's own encoding; the
/// Python side writes the same layout through meshio: `fsm.export`).

#include <cstdint>
#include <string>
#include <vector>

#include "fsm/skinning.hpp"
#include "fsm/sphere_model.hpp"
#include "fsm/types.hpp"

namespace fsm {

/// @brief Writes states of one model as a ParaView time series in a folder.
class VtkSeriesWriter {
 public:
  /// @brief Creates `directory` if needed. `skin` may be null (no surface piece). The model and
  /// skin must outlive the writer. fsm::Error if the folder cannot be made or `name` is empty or
  /// holds a path separator.
  VtkSeriesWriter(const std::string& directory, const SphereModel<double>& model,
                  const Skin<double>* skin = nullptr, const std::string& name = "fsm");

  /// @brief Writes one state at `time` (s): positions, velocities and forces are `|V| x 3`;
  /// `surface` (the skinned render surface, `skin->rest.vertices` sized) is used when the writer
  /// has a skin (null: the rest surface). fsm::Error naming the file on a wrong size, a time not
  /// after the previous one, or a failed write.
  void write(double time, const Eigen::Ref<const Positions<double>>& positions,
             const Eigen::Ref<const Positions<double>>& velocities,
             const Eigen::Ref<const Positions<double>>& forces,
             const Positions<double>* surface = nullptr);

  [[nodiscard]] std::size_t states() const noexcept { return m_times.size(); }
  [[nodiscard]] std::string series_path() const;  ///< DIR/NAME.pvd

 private:
  void write_index() const;
  std::string m_directory, m_name;
  const SphereModel<double>& m_model;
  const Skin<double>* m_skin;
  std::vector<double> m_times;
};

}  // namespace fsm
