// MakeHuman's macro sliders as options (--gender … --firmness, each in [0, 1]), shared by the
// verbs that build a MakeHuman body from sliders (makehuman-body, dress).
#pragma once

#include <CLI/CLI.hpp>

#include "core/makehuman.h"

namespace bodymodel::cli {

inline void add_macro_slider_options(CLI::App* cmd, MacroSettings& s) {
  auto slider = [&](const char* flag, double* v, const char* help) {
    cmd->add_option(flag, *v, help)->check(CLI::Range(0.0, 1.0))->capture_default_str();
  };
  slider("--gender", &s.gender, "0 female … 1 male");
  slider("--age", &s.age, "0 = 1 y, 0.1875 = 10 y, 0.5 = 25 y, 1 = 90 y");
  slider("--muscle", &s.muscle, "muscle mass");
  slider("--weight", &s.weight, "body weight");
  slider("--height", &s.height, "body height");
  slider("--proportions", &s.proportions, "0 uncommon … 1 ideal proportions");
  slider("--cup", &s.cup, "breast size (female bodies)");
  slider("--firmness", &s.firmness, "breast firmness (female bodies)");
}

}  // namespace bodymodel::cli
