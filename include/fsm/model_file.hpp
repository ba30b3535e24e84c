#pragma once

/// @file model_file.hpp
/// @brief The versioned model file (.fsm): a TissueModel written by the offline builder and read
/// by the runtime without CGAL.
///
/// A binary, little-endian file: a 32-byte header (magic, format version, flags, payload length,
/// payload CRC-32, header CRC-32) and a payload of tagged sections (tag, length, bytes) that a
/// reader skips when it does not know the tag. docs/model_file.md gives the byte-level layout,
/// the versioning policy and every error the reader reports.
///
/// Every value is stored exactly (doubles bit for bit, so +infinity switch strains and negative
/// zeros survive); writing then reading gives back an identical model.

#include <cstdint>
#include <string>

#include "fsm/tissue_model.hpp"

namespace fsm {

/// @brief Current format version written by save_model().
///
/// A reader accepts every version up to its own and refuses a newer one ("model file version 3
/// is newer than this runtime (2)"). Version 2 added the tetrahedral parts' tetrahedra (section
/// `TETS`, and each part's range of them); a version 1 file loads with none. The version goes up
/// when an older reader would misread a file; additions an older reader may ignore go into new
/// sections at the same version.
inline constexpr std::uint32_t model_file_version = 4;

/// @brief Writes `model` to the file `path` (created or overwritten) in the current format.
///
/// The model is validated first (TissueModel::validate()), so a file that was written can always
/// be read back.
/// @param path the file to write; by convention it ends in `.fsm`.
/// @param model the model: spheres (positions in m, velocities in m/s, masses in kg, ...), parts,
/// attachment range, skin, name and report.
/// @throws fsm::Error with `file()` = `path`: the model fails validation (the validator's part
/// and reason), or the file cannot be opened, written or closed (the system's reason).
void save_model(const std::string& path, const TissueModel<double>& model);

/// @brief Reads the model file `path`.
///
/// Checks, in order: the file opens and is not empty, the magic bytes, the format version, the
/// header's length and CRC-32, the payload's length and CRC-32, every section's framing, and
/// finally the content: the SphereModel is rebuilt through its public API and the whole model is
/// checked by TissueModel::validate().
/// @param path the file to read.
/// @return the model, identical to the one that was saved.
/// @throws fsm::Error with `file()` = `path` and a reason: the file is missing or unreadable,
/// empty, not a model file (bad magic), truncated, corrupt (CRC mismatch), of a newer version,
/// malformed, or its content fails validation (the validator's part and reason).
[[nodiscard]] TissueModel<double> load_model(const std::string& path);

/// @brief The bytes save_model() would write for `model`, in memory.
/// @throws fsm::Error (empty `file()`) when the model fails validation.
[[nodiscard]] std::string serialize_model(const TissueModel<double>& model);

/// @brief Reads a model from the bytes of a model file, as load_model() reads a file.
/// @param bytes the file's bytes.
/// @param file the name to report in errors (`fsm::Error::file()`); may be empty.
/// @throws fsm::Error as load_model() does, naming `file`.
[[nodiscard]] TissueModel<double> deserialize_model(const std::string& bytes,
                                                    const std::string& file = "");

}  // namespace fsm
