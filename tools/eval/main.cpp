// omnipose-eval: scores estimated trajectories against ground truth, per frame pair.
#include <cstdio>
#include <exception>
#include <fstream>
#include <string>
#include <vector>

#include "omnipose/evaluation.hpp"
#include "omnipose/trajectory.hpp"

namespace {

void usage(std::FILE* out) {
  std::fprintf(out,
               "usage: omnipose-eval GT.tum EST.tum [EST2.tum ...] [--json OUT.json]\n"
               "                     [--pairs OUT.csv] [--tolerance SECONDS]\n"
               "  Per consecutive ground-truth pair: rotation-vector error (roll x, pitch y,\n"
               "  yaw z), rotation angle error eps, translation-direction error; RMSE and max.\n"
               "  --json   all results as a JSON array (one object per estimate)\n"
               "  --pairs  per-pair errors of the first estimate as CSV\n");
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::string> files;
  std::string json_path, pairs_path;
  omnipose::EvaluationOptions options;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "-h" || arg == "--help") {
      usage(stdout);
      return 0;
    }
    if ((arg == "--json" || arg == "--pairs" || arg == "--tolerance") && i + 1 >= argc) {
      std::fprintf(stderr, "omnipose-eval: %s needs a value\n", arg.c_str());
      return 2;
    }
    if (arg == "--json") json_path = argv[++i];
    else if (arg == "--pairs") pairs_path = argv[++i];
    else if (arg == "--tolerance") options.time_tolerance = std::stod(argv[++i]);
    else if (!arg.empty() && arg[0] == '-') {
      std::fprintf(stderr, "omnipose-eval: unknown option %s\n", arg.c_str());
      return 2;
    } else files.push_back(arg);
  }
  if (files.size() < 2) {
    usage(stderr);
    return 2;
  }
  try {
    const auto gt = omnipose::readTum(files[0]);
    std::string json = "[";
    for (std::size_t i = 1; i < files.size(); ++i) {
      const auto result = omnipose::evaluate(gt, omnipose::readTum(files[i]), options);
      std::fputs(omnipose::formatTable(result, files[i]).c_str(), stdout);
      json += (i > 1 ? ",\n " : "") + omnipose::formatJson(result, files[i]);
      if (i == 1 && !pairs_path.empty()) {
        std::ofstream out(pairs_path);
        if (!out) throw std::runtime_error(pairs_path + ": cannot write");
        out << omnipose::formatPairsCsv(result);
      }
    }
    json += "]\n";
    if (!json_path.empty()) {
      std::ofstream out(json_path);
      if (!out) throw std::runtime_error(json_path + ": cannot write");
      out << json;
    }
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "omnipose-eval: %s\n", e.what());
    return 1;
  }
}
