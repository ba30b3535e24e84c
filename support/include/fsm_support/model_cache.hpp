#pragma once

/// @file fsm_support/model_cache.hpp
/// @brief The model the demo, the viewer and the benchmarks open: a model file, a scene to build,
/// or (by default) the bundled uterus, built on first run and cached. Support code for the
/// programs around the library, not part of it.

#include <sys/stat.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <string>

#include "fsm/model_file.hpp"

namespace fsm::support {

/// Last modification time of a file (s), or -1 when it does not exist.
inline double mtime(const std::string& path) {
  struct stat st {};
  return stat(path.c_str(), &st) == 0 ? double(st.st_mtime) : -1;
}

/// $FSM_CACHE_DIR, else $XDG_CACHE_HOME/fsm, else ~/.cache/fsm.
inline std::string cache_dir() {
  if (const char* d = std::getenv("FSM_CACHE_DIR")) return d;
  if (const char* d = std::getenv("XDG_CACHE_HOME")) return std::string(d) + "/fsm";
  if (const char* d = std::getenv("HOME")) return std::string(d) + "/.cache/fsm";
  return ".fsm-cache";
}

/// mkdir -p (errors show up when a file is written there).
inline void make_dirs(const std::string& path) {
  std::string p;
  for (std::size_t i = 0; i <= path.size(); ++i) {
    if ((i == path.size() || path[i] == '/') && !p.empty()) mkdir(p.c_str(), 0755);
    if (i < path.size()) p += path[i];
  }
}

struct OpenedModel {
  TissueModel<double> model;
  std::string source;  ///< the file read or the scene built
  bool built{false};   ///< built now (not read from a model file or the cache)
  double build_seconds{0};
};

/// The source tree's data/ folder (the support target's compile definition), or "data".
inline std::string source_data_dir() {
#ifdef FSM_SUPPORT_DATA_DIR
  return FSM_SUPPORT_DATA_DIR;
#else
  return "data";
#endif
}

/// `model`: a model file, a scene (.json) to build, or empty for the bundled uterus
/// ($FSM_DATA_DIR or `default_data_dir`), cached in cache_dir() and rebuilt when the scene or
/// a mesh is newer than the cache or the cache cannot be read. `build` builds a scene (the
/// builder is GPL and optional, so the caller passes it). `who` names the program in messages.
inline OpenedModel open_model(const std::string& model, const std::string& default_data_dir,
                              const std::function<TissueModel<double>(const std::string&)>& build,
                              const char* who) {
  OpenedModel o;
  auto build_now = [&](const std::string& scene) {
    const auto t0 = std::chrono::steady_clock::now();
    o.model = build(scene);
    o.source = scene;
    o.built = true;
    o.build_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  };
  if (model.size() > 5 && model.substr(model.size() - 5) == ".json") {
    build_now(model);
    return o;
  }
  if (!model.empty()) {
    o.model = load_model(model);
    o.source = model;
    return o;
  }
  const char* data = std::getenv("FSM_DATA_DIR");
  const std::string dir = data != nullptr ? std::string(data) : default_data_dir;
  const std::string scene = dir + "/uterus/uterus.json";
  const std::string cached = cache_dir() + "/uterus.fsm";
  // The cache is stale when the scene or any file beside it (its meshes) is newer.
  double newest = mtime(scene);
  std::error_code ec;
  for (const auto& e : std::filesystem::directory_iterator(dir + "/uterus", ec))
    newest = std::max(newest, mtime(e.path().string()));
  if (mtime(cached) >= newest && newest > 0) {
    try {
      o.model = load_model(cached);
      o.source = cached;
      return o;
    } catch (const Error&) {
      // stale or corrupt cache (e.g. an older format): rebuild below
    }
  }
  build_now(scene);
  try {
    make_dirs(cache_dir());
    save_model(cached, o.model);
  } catch (const Error& e) {
    std::fprintf(stderr, "%s: could not cache the model (%s); continuing\n", who, e.what());
  }
  return o;
}

/// @brief The bundled uterus, opened once per process through the cache (built with `build` when
/// the cache is missing or stale). For benchmarks and tools that press the default model.
inline const TissueModel<double>& bundled_uterus(
    const std::function<TissueModel<double>(const std::string&)>& build, const char* who) {
  static const TissueModel<double> model = open_model("", source_data_dir(), build, who).model;
  return model;
}

}  // namespace fsm::support
