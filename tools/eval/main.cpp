// omnipose-eval: scores estimated trajectories against ground truth, per frame pair.
#include <cstdio>
#include <exception>
#include <fstream>
#include <string>
#include <vector>

#include "cli.hpp"
#include "omnipose/evaluation.hpp"
#include "omnipose/trajectory.hpp"

int main(int argc, char** argv) {
  std::vector<std::string> files;
  std::string json_path, pairs_path;
  omnipose::EvaluationOptions options;
  omnipose::tools::Cli cli(
      "omnipose-eval",
      "usage: omnipose-eval GT.tum EST.tum [EST2.tum ...] [--json OUT.json]\n"
      "                     [--pairs OUT.csv] [--tolerance SECONDS]",
      "Per consecutive ground-truth pair: rotation-vector error (roll x, pitch y, yaw z; rad),\n"
      "rotation angle error eps (rad), translation-direction error (rad); RMSE and max.\n"
      "Exit codes: 0 scored, 1 a file cannot be read or written, 2 bad command line.");
  auto& app = cli.app();
  app.add_option("FILES", files,
                 "GT.tum EST.tum [EST2.tum ...]: the ground-truth trajectory, then one or more "
                 "estimated ones (TUM format: timestamp s, position, quaternion)")
      ->required();
  app.add_option("--json", json_path, "all results as a JSON array (one object per estimate)")
      ->type_name("OUT.json");
  app.add_option("--pairs", pairs_path, "per-pair errors of the first estimate as CSV")
      ->type_name("OUT.csv");
  app.add_option("--tolerance", options.time_tolerance,
                 "largest timestamp difference, seconds, at which an estimated pose matches a "
                 "ground-truth pose")
      ->type_name("SECONDS")
      ->capture_default_str();
  if (const auto exit_code = cli.parse(argc, argv)) return *exit_code;
  if (files.size() < 2) return cli.usageError("FILES: give GT.tum and at least one EST.tum");
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
