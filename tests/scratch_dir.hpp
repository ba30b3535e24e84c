#pragma once

// A scratch folder of the running test's own. ctest runs every discovered test as its own process,
// two at a time, so fixtures of one suite run side by side: a folder named after the suite alone is
// removed by one test while the other writes into it. The test's full name and the process id keep
// them apart.

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <string>

namespace fsm::test {

/// `<tmp>/<prefix>_<suite>_<test>_<pid>`, emptied and created. Parameterised names keep their '/'
/// out of the path.
inline std::filesystem::path scratch_dir(const std::string& prefix) {
  const ::testing::TestInfo* info = ::testing::UnitTest::GetInstance()->current_test_info();
  std::string name = prefix;
  if (info != nullptr) name += std::string("_") + info->test_suite_name() + "_" + info->name();
  for (char& c : name)
    if (c == '/') c = '_';
  name += "_" + std::to_string(::getpid());
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / name;
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

}  // namespace fsm::test
