#pragma once

/// @file error.hpp
/// @brief fsm::Error, the one exception type libfsm throws for bad input.

#include <stdexcept>
#include <string>
#include <utility>

namespace fsm {

/// @brief Bad input: a file, a part or a value that cannot be used, and why.
///
/// Thrown at construction and loading time only; nothing inside a real-time step throws.
/// `what()` reads "file: part: reason" with the empty fields left out.
class Error : public std::runtime_error {
 public:
  /// @brief An error with a reason only.
  explicit Error(std::string reason) : Error(std::string(), std::string(), std::move(reason)) {}

  /// @brief An error naming the file and the part (either may be empty) and the reason.
  Error(std::string file, std::string part, std::string reason)
      : std::runtime_error(compose(file, part, reason)),
        m_file(std::move(file)),
        m_part(std::move(part)),
        m_reason(std::move(reason)) {}

  /// @brief The file the error is about, or empty.
  [[nodiscard]] const std::string& file() const noexcept { return m_file; }
  /// @brief The part, element or parameter the error is about, or empty.
  [[nodiscard]] const std::string& part() const noexcept { return m_part; }
  /// @brief Why the input cannot be used.
  [[nodiscard]] const std::string& reason() const noexcept { return m_reason; }

 private:
  static std::string compose(const std::string& file, const std::string& part,
                             const std::string& reason) {
    std::string s;
    if (!file.empty()) s += file + ": ";
    if (!part.empty()) s += part + ": ";
    return s + reason;
  }

  std::string m_file;
  std::string m_part;
  std::string m_reason;
};

}  // namespace fsm
