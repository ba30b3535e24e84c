// Crafted model files (tests/malformed/model): valid CRCs in front of counts near 2^31, ranges
// past the end, inverted tetrahedra, NaN values, broken framing. Each must be refused with an
// fsm::Error naming the file and saying what is wrong (the words in manifest.json) - never a
// crash, an uncaught exception or a huge allocation (this test also runs under ASan and UBSan).

#include <gtest/gtest.h>

#include "fsm/model_file.hpp"
#include "malformed.hpp"

namespace fsm {
namespace {

TEST(MalformedModels, EveryCraftedFileIsRefusedWithItsReason) {
  const auto cases = test::malformed_inputs("model");
  ASSERT_GE(cases.size(), 50u);
  for (const auto& [path, words] : cases) {
    SCOPED_TRACE(path);
    try {
      (void)load_model(path);
      ADD_FAILURE() << "loaded without an error";
    } catch (const Error& e) {
      EXPECT_EQ(e.file(), path);
      EXPECT_NE(std::string(e.what()).find(words), std::string::npos)
          << "wanted '" << words << "' in: " << e.what();
    }
  }
}

}  // namespace
}  // namespace fsm
