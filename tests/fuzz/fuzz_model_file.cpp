// libFuzzer target: the model-file reader on arbitrary bytes. Anything but a model or an
// fsm::Error (a crash, a hang, a sanitizer report, another exception) is a finding.
//
// A CRC stops almost every mutation at the header, so for inputs whose size is even the target
// first makes the header agree with the payload (length, payload CRC-32, header CRC-32): the
// mutations then reach the sections, the counts and the ranges, which is where a crafted file
// attacks (docs/model_file.md).

#include <cstddef>
#include <cstdint>
#include <string>

#include "fsm/model_file.hpp"

namespace {

std::uint32_t crc32(const std::string& b, std::size_t begin, std::size_t end) {
  std::uint32_t c = 0xFFFFFFFFu;
  for (std::size_t i = begin; i < end; ++i) {
    c ^= static_cast<unsigned char>(b[i]);
    for (int k = 0; k < 8; ++k) c = (c >> 1) ^ (0xEDB88320u & (0u - (c & 1u)));
  }
  return ~c;
}

void put_le(std::string& b, std::size_t at, std::uint64_t v, int n) {
  for (int k = 0; k < n; ++k)
    b[at + std::size_t(k)] = static_cast<char>(static_cast<unsigned char>(v >> (8 * k)));
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  std::string bytes(reinterpret_cast<const char*>(data), size);
  if (size % 2 == 0 && size >= 32) {
    put_le(bytes, 16, size - 32, 8);
    put_le(bytes, 24, crc32(bytes, 32, size), 4);
    put_le(bytes, 28, crc32(bytes, 0, 28), 4);
  }
  try {
    const fsm::TissueModel<double> model = fsm::deserialize_model(bytes, "fuzz.fsm");
    // A model that loads must be usable: written again, it loads to the same bytes.
    const std::string again = fsm::serialize_model(model);
    if (fsm::serialize_model(fsm::deserialize_model(again)) != again) __builtin_trap();
  } catch (const fsm::Error&) {
  }
  return 0;
}
