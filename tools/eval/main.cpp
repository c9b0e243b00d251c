// omnipose-eval: scores estimated trajectories against ground truth, per frame pair.
#include <cstdio>
#include <exception>
#include <fstream>
#include <string>
#include <vector>

#include "cli.hpp"
#include "omnipose/eval/evaluation.hpp"
#include "omnipose/io/trajectory.hpp"

int main(int argc, char** argv) {
  std::vector<std::string> files;
  std::string json_path, pairs_path, drift_csv_path;
  bool drift = false;
  omnipose::EvaluationOptions options;
  omnipose::tools::Cli cli(
      "omnipose-eval",
      "usage: omnipose-eval GT.tum EST.tum [EST2.tum ...] [--json OUT.json]\n"
      "                     [--pairs OUT.csv] [--tolerance SECONDS]\n"
      "       omnipose-eval --drift GT.tum EST.tum [EST2.tum ...] [--json OUT.json]\n"
      "                     [--drift-csv OUT.csv] [--tolerance SECONDS]",
      "Per consecutive ground-truth pair: rotation-vector error (roll x, pitch y, yaw z; rad),\n"
      "rotation angle error eps (rad), translation-direction error (rad); RMSE and max.\n"
      "--drift: the chained attitude's drift instead (omnipose::evaluateDrift): the estimate\n"
      "aligned by its first pose, the rotation error angle at the last matched pose\n"
      "(end-point), its RMSE over all matched poses (ATE) and its maximum, in degrees, with\n"
      "the per-pair eps RMSE in mrad beside; --json then holds the drift objects (radians).\n"
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
  app.add_flag("--drift", drift, "score the drift of the chained attitude (see above)");
  app.add_option("--drift-csv", drift_csv_path,
                 "with --drift: the rotation error angle of every matched pose of the first "
                 "estimate as CSV (t, error_rad)")
      ->type_name("OUT.csv");
  app.add_option("--tolerance", options.time_tolerance,
                 "largest timestamp difference, seconds, at which an estimated pose matches a "
                 "ground-truth pose")
      ->type_name("SECONDS")
      ->capture_default_str();
  if (const auto exit_code = cli.parse(argc, argv)) return *exit_code;
  if (files.size() < 2) return cli.usageError("FILES: give GT.tum and at least one EST.tum");
  if (!drift_csv_path.empty() && !drift) return cli.usageError("--drift-csv needs --drift");
  if (drift && !pairs_path.empty()) return cli.usageError("--pairs is not a --drift output");
  auto write = [](const std::string& path, const std::string& text) {
    std::ofstream out(path);
    if (!out || !(out << text)) throw std::runtime_error(path + ": cannot write");
  };
  try {
    const auto gt = omnipose::readTum(files[0]);
    std::string json = "[";
    for (std::size_t i = 1; i < files.size(); ++i) {
      const auto estimate = omnipose::readTum(files[i]);
      const auto result = omnipose::evaluate(gt, estimate, options);
      if (drift) {
        omnipose::DriftResult d;
        try {
          d = omnipose::evaluateDrift(gt, estimate, options);
        } catch (const std::invalid_argument& e) {
          throw std::runtime_error(files[i] + ": " + e.what());
        }
        std::fputs(omnipose::formatDriftTable(d, result, files[i]).c_str(), stdout);
        json += (i > 1 ? ",\n " : "") + omnipose::formatDriftJson(d, result, files[i]);
        if (i == 1 && !drift_csv_path.empty()) write(drift_csv_path, omnipose::formatDriftCsv(d));
        continue;
      }
      std::fputs(omnipose::formatTable(result, files[i]).c_str(), stdout);
      json += (i > 1 ? ",\n " : "") + omnipose::formatJson(result, files[i]);
      if (i == 1 && !pairs_path.empty()) write(pairs_path, omnipose::formatPairsCsv(result));
    }
    json += "]\n";
    if (!json_path.empty()) write(json_path, json);
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "omnipose-eval: %s\n", e.what());
    return 1;
  }
}
