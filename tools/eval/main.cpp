// omnipose-eval: scores estimated trajectories against ground truth, per frame pair.
#include <cstdio>
#include <exception>
#include <fstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "cli.hpp"
#include "omnipose/eval/evaluation.hpp"
#include "omnipose/io/trajectory.hpp"

namespace {

/// The command line, as parsed.
struct Args {
  std::vector<std::string> files;
  std::string json_path, pairs_path, drift_csv_path;
  bool drift = false;
  omnipose::EvaluationOptions options;
};

constexpr const char* kUsage =
    "usage: omnipose-eval GT.tum EST.tum [EST2.tum ...] [--json OUT.json]\n"
    "                     [--pairs OUT.csv] [--tolerance SECONDS]\n"
    "       omnipose-eval --drift GT.tum EST.tum [EST2.tum ...] [--json OUT.json]\n"
    "                     [--drift-csv OUT.csv] [--tolerance SECONDS]";

constexpr const char* kDescription =
    "Per consecutive ground-truth pair: rotation-vector error (roll x, pitch y, yaw z; rad),\n"
    "rotation angle error eps (rad), translation-direction error (rad); RMSE and max.\n"
    "--drift: the chained attitude's drift instead (omnipose::evaluateDrift): the estimate\n"
    "aligned by its first pose, the rotation error angle at the last matched pose\n"
    "(end-point), its RMSE over all matched poses (ATE) and its maximum, in degrees, with\n"
    "the per-pair eps RMSE in mrad beside; --json then holds the drift objects (radians).\n"
    "Exit codes: 0 scored, 1 a file cannot be read or written, 2 bad command line.";

void addOptions(CLI::App& app, Args& a) {
  app.add_option("FILES", a.files,
                 "GT.tum EST.tum [EST2.tum ...]: the ground-truth trajectory, then one or more "
                 "estimated ones (TUM format: timestamp s, position, quaternion)")
      ->required();
  app.add_option("--json", a.json_path, "all results as a JSON array (one object per estimate)")
      ->type_name("OUT.json");
  app.add_option("--pairs", a.pairs_path, "per-pair errors of the first estimate as CSV")
      ->type_name("OUT.csv");
  app.add_flag("--drift", a.drift, "score the drift of the chained attitude (see above)");
  app.add_option("--drift-csv", a.drift_csv_path,
                 "with --drift: the rotation error angle of every matched pose of the first "
                 "estimate as CSV (t, error_rad)")
      ->type_name("OUT.csv");
  app.add_option("--tolerance", a.options.time_tolerance,
                 "largest timestamp difference, seconds, at which an estimated pose matches a "
                 "ground-truth pose")
      ->type_name("SECONDS")
      ->capture_default_str();
}

void writeText(const std::string& path, const std::string& text) {
  std::ofstream out(path);
  if (!out || !(out << text)) throw std::runtime_error(path + ": cannot write");
}

/// Scores every estimate against the ground truth, prints the tables, writes the files.
int score(const Args& a) {
  const auto gt = omnipose::readTum(a.files[0]);
  std::string json = "[";
  for (std::size_t i = 1; i < a.files.size(); ++i) {
    const std::string& file = a.files[i];
    const auto estimate = omnipose::readTum(file);
    const auto result = omnipose::evaluate(gt, estimate, a.options);
    if (a.drift) {
      omnipose::DriftResult d;
      try {
        d = omnipose::evaluateDrift(gt, estimate, a.options);
      } catch (const std::invalid_argument& e) {
        throw std::runtime_error(file + ": " + e.what());
      }
      std::fputs(omnipose::formatDriftTable(d, result, file).c_str(), stdout);
      json += (i > 1 ? ",\n " : "") + omnipose::formatDriftJson(d, result, file);
      if (i == 1 && !a.drift_csv_path.empty()) writeText(a.drift_csv_path, omnipose::formatDriftCsv(d));
      continue;
    }
    std::fputs(omnipose::formatTable(result, file).c_str(), stdout);
    json += (i > 1 ? ",\n " : "") + omnipose::formatJson(result, file);
    if (i == 1 && !a.pairs_path.empty()) writeText(a.pairs_path, omnipose::formatPairsCsv(result));
  }
  json += "]\n";
  if (!a.json_path.empty()) writeText(a.json_path, json);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  using omnipose::tools::Cli;
  return omnipose::tools::runMain<Args>(
      argc, argv, {"omnipose-eval", kUsage, kDescription}, addOptions,
      [](Cli& cli, const Args& args) {
        if (args.files.size() < 2) return cli.usageError("FILES: give GT.tum and at least one EST.tum");
        if (!args.drift_csv_path.empty() && !args.drift) return cli.usageError("--drift-csv needs --drift");
        if (args.drift && !args.pairs_path.empty()) return cli.usageError("--pairs is not a --drift output");
        return score(args);
      });
}
