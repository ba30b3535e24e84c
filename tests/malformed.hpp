#pragma once

// The malformed-input corpus (tests/malformed, written by generate.py): each file with the words
// its error must contain, from manifest.json.

#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <string>

namespace fsm::test {

/// Path (absolute) -> expected words, for the files under tests/malformed/<kind>/.
inline std::map<std::string, std::string> malformed_inputs(const std::string& kind) {
  const std::string dir = FSM_MALFORMED_DIR;
  std::ifstream in(dir + "/manifest.json");
  const nlohmann::json manifest = nlohmann::json::parse(in);
  std::map<std::string, std::string> out;
  for (const auto& [file, words] : manifest.items())
    if (file.rfind(kind + "/", 0) == 0) out[dir + "/" + file] = words.get<std::string>();
  return out;
}

}  // namespace fsm::test
