// omnipose-results: the Markdown tables of the accuracy benchmark, in the layout of the
// paper's Table I, from a manifest of (scene, sequence, method, GT.tum, EST.tum, seconds
// per frame) rows. Scores with omnipose::evaluate (the same as omnipose-eval).
//
// Table I (single-axis sequences roll / pitch / yaw per scene):
//   cell         RMSE of the rotation-vector error component about the moved axis, mrad
//   avg          mean of a column over the scenes (the paper's "average error")
//   eps          mean of the three averages (the paper's epsilon)
//   3-D angle    RMSE of the full rotation error angle over all pairs of these sequences
//                (also counts error leaking into the other two axes)
//   time         mean over all sequences of the median seconds per frame
// Table II (every other sequence): RMSE of the rotation error angle (mrad), and of the
// translation direction error (degrees) where the ground truth translates.
// Lost pairs (no estimate) are not in an RMSE; cells show their count as "(n lost)".

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <exception>
#include <fstream>
#include <limits>
#include <map>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "cli.hpp"
#include "omnipose/eval/evaluation.hpp"
#include "omnipose/file_io.hpp"
#include "omnipose/io/trajectory.hpp"

namespace {

using namespace omnipose;

struct Run {
  std::string scene, sequence, method;
  EvaluationResult result;
  double seconds = 0.0;
  bool estimates_translation = false;  ///< false: every estimated position is the origin
};

/// Whether a trajectory ever leaves the origin (rotation-only methods never do).
bool translates(const std::vector<StampedPose>& poses) {
  for (const StampedPose& p : poses)
    if (p.pose.translation().norm() > 0) return true;
  return false;
}

struct Cell {
  std::optional<double> value;
  int lost = 0;
};

bool isAxis(const std::string& s) { return s == "roll" || s == "pitch" || s == "yaw"; }
int axisIndex(const std::string& s) { return s == "roll" ? 0 : s == "pitch" ? 1 : 2; }

std::string format(const Cell& c, bool bold) {
  if (!c.value) return "–";
  char buf[64];
  std::snprintf(buf, sizeof(buf), bold ? "**%.3f**" : "%.3f", *c.value);
  std::string s = buf;
  if (c.lost > 0) s += " (" + std::to_string(c.lost) + " lost)";
  return s;
}

/// A table: columns of cells per method, printed with the best (lowest) value in bold.
struct Table {
  std::vector<std::string> columns;
  std::vector<bool> rotation;  ///< whether a column is a rotation error (for the notes)
  std::map<std::string, std::vector<Cell>> rows;

  void addColumn(const std::string& name, bool is_rotation) {
    columns.push_back(name);
    rotation.push_back(is_rotation);
  }

  std::string markdown(const std::vector<std::string>& methods, bool bold_best = true,
                       int plain_from = -1) const {
    std::string s = "| method |";
    for (const auto& c : columns) s += " " + c + " |";
    s += "\n|---|";
    for (std::size_t i = 0; i < columns.size(); ++i) s += "---:|";
    s += "\n";
    for (const auto& m : methods) {
      s += "| " + m + " |";
      const auto& cells = rows.at(m);
      for (std::size_t i = 0; i < columns.size(); ++i) {
        double best = std::numeric_limits<double>::infinity();
        for (const auto& other : methods)
          if (rows.at(other)[i].value) best = std::min(best, *rows.at(other)[i].value);
        const bool bold = bold_best && (plain_from < 0 || static_cast<int>(i) < plain_from) &&
                          cells[i].value && *cells[i].value <= best;
        s += " " + format(cells[i], bold) + " |";
      }
      s += "\n";
    }
    return s;
  }
};

/// The manifest's runs, scored, and the names in order of appearance.
struct Manifest {
  std::vector<Run> runs;
  std::vector<std::string> scenes;   ///< scenes with roll|pitch|yaw sequences (Table I)
  std::vector<std::string> methods;
  std::vector<std::string> others;   ///< "scene sequence" of every other sequence (Table II)

  const Run* find(const std::string& scene, const std::string& seq,
                  const std::string& method) const {
    for (const Run& r : runs)
      if (r.scene == scene && r.sequence == seq && r.method == method) return &r;
    return nullptr;
  }
};

/// Reads and scores every run of the manifest.
Manifest readManifest(const std::string& manifest) {
  std::istringstream in(omnipose::readTextFileOrThrow(manifest));
  Manifest m;
  auto remember = [](std::vector<std::string>& list, const std::string& v) {
    if (std::find(list.begin(), list.end(), v) == list.end()) list.push_back(v);
  };
  int line_no = 0;
  for (std::string line; std::getline(in, line);) {
    ++line_no;
    if (line.empty() || line[0] == '#') continue;
    std::vector<std::string> f;
    std::stringstream ss(line);
    for (std::string part; std::getline(ss, part, '\t');) f.push_back(part);
    if (f.size() != 6)
      throw std::runtime_error(manifest + ":" + std::to_string(line_no) + ": expected 6 fields");
    const std::vector<StampedPose> estimate = readTum(f[4]);
    Run r{f[0], f[1], f[2], evaluate(readTum(f[3]), estimate), std::stod(f[5]),
          translates(estimate)};
    if (isAxis(r.sequence)) remember(m.scenes, r.scene);
    else remember(m.others, r.scene + " " + r.sequence);
    remember(m.methods, r.method);
    m.runs.push_back(std::move(r));
  }
  return m;
}

/// Table I's row of method `method`: a cell per scene and axis, the three averages, eps,
/// the 3-D angle and the time.
std::vector<Cell> tableOneRow(const Manifest& manifest, const std::string& method) {
  std::vector<Cell> cells;
  double avg_sum[3] = {0, 0, 0};
  int avg_n[3] = {0, 0, 0};
  double angle_sq = 0.0;
  int angle_n = 0, lost_total = 0;
  for (const auto& scene : manifest.scenes) {
    for (const char* axis : {"roll", "pitch", "yaw"}) {
      const Run* r = manifest.find(scene, axis, method);
      Cell c;
      if (r && !r->result.pairs.empty()) {
        const int a = axisIndex(axis);
        const ErrorStats& s = a == 0 ? r->result.roll : a == 1 ? r->result.pitch : r->result.yaw;
        c.value = 1e3 * s.rmse;
        c.lost = r->result.pairs_missing;
        avg_sum[a] += 1e3 * s.rmse;
        ++avg_n[a];
        angle_sq += r->result.angle.rmse * r->result.angle.rmse * r->result.angle.count;
        angle_n += r->result.angle.count;
      } else if (r) {
        c.lost = r->result.pairs_missing;
      }
      if (r) lost_total += r->result.pairs_missing;
      cells.push_back(c);
    }
  }
  double eps = 0.0;
  bool eps_ok = true;
  for (int a = 0; a < 3; ++a) {
    Cell c;
    if (avg_n[a] > 0) c.value = avg_sum[a] / avg_n[a];
    else eps_ok = false;
    if (c.value) eps += *c.value / 3.0;
    cells.push_back(c);
  }
  cells.push_back(eps_ok ? Cell{eps, 0} : Cell{});
  cells.push_back(angle_n > 0 ? Cell{1e3 * std::sqrt(angle_sq / angle_n), lost_total} : Cell{});
  double sec = 0.0;
  int n = 0;
  for (const Run& r : manifest.runs)
    if (r.method == method) sec += r.seconds, ++n;
  cells.push_back(Cell{n > 0 ? sec / n : 0.0, 0});
  return cells;
}

/// Table I: the single-axis sequences per scene. Its last column (time) is not bolded.
Table tableOne(const Manifest& manifest) {
  Table t1;
  for (const auto& scene : manifest.scenes)
    for (const char* axis : {"roll", "pitch", "yaw"}) t1.addColumn(scene + " " + axis, true);
  for (const char* axis : {"roll", "pitch", "yaw"}) t1.addColumn(std::string("avg ") + axis, true);
  t1.addColumn("ε", true);
  t1.addColumn("3-D angle", true);
  t1.addColumn("time [s]", false);
  for (const auto& m : manifest.methods) t1.rows[m] = tableOneRow(manifest, m);
  return t1;
}

/// Table II: every other sequence, the rotation angle and (where the ground truth
/// translates) the translation direction.
Table tableTwo(const Manifest& manifest) {
  Table t2;
  std::vector<std::pair<std::string, bool>> t2_columns;  // (scene sequence, translation?)
  for (const auto& o : manifest.others) {
    const auto space = o.find(' ');
    const std::string scene = o.substr(0, space), seq = o.substr(space + 1);
    bool translates = false;
    for (const Run& r : manifest.runs)
      if (r.scene == scene && r.sequence == seq && r.result.translation_direction.count > 0)
        translates = true;
    t2.addColumn(o + " angle", true);
    if (translates) t2.addColumn(o + " t-dir", false);
    t2_columns.emplace_back(o, translates);
  }
  for (const auto& m : manifest.methods) {
    std::vector<Cell> cells;
    for (const auto& [o, translates] : t2_columns) {
      const auto space = o.find(' ');
      const Run* r = manifest.find(o.substr(0, space), o.substr(space + 1), m);
      Cell angle, tdir;
      if (r) {
        angle.lost = tdir.lost = r->result.pairs_missing;
        if (r->result.angle.count > 0) angle.value = 1e3 * r->result.angle.rmse;
        if (r->result.translation_direction.count > 0 && r->estimates_translation)
          tdir.value = r->result.translation_direction.rmse * 180.0 / M_PI;
      }
      cells.push_back(angle);
      if (translates) cells.push_back(tdir);
    }
    t2.rows[m] = cells;
  }
  return t2;
}

/// A note for every rotation column of `t` where some method is below `main_method`.
std::string notesAgainst(const Table& t, const char* table_name, const std::string& main_method,
                         const std::vector<std::string>& methods) {
  std::string notes;
  for (std::size_t i = 0; i < t.columns.size(); ++i) {
    if (!t.rotation[i]) continue;
    const Cell& mine = t.rows.at(main_method)[i];
    for (const auto& m : methods) {
      if (m == main_method) continue;
      const Cell& other = t.rows.at(m)[i];
      if (!other.value) continue;
      char buf[320];
      if (!mine.value) {
        std::snprintf(buf, sizeof(buf), "- %s, %s: %s has no estimate, %s %.3f\n", table_name,
                      t.columns[i].c_str(), main_method.c_str(), m.c_str(), *other.value);
        notes += buf;
      } else if (*other.value < *mine.value) {
        std::snprintf(buf, sizeof(buf), "- %s, %s: %s %.3f < %s %.3f (%s is %.2fx larger)%s\n",
                      table_name, t.columns[i].c_str(), m.c_str(), *other.value,
                      main_method.c_str(), *mine.value, main_method.c_str(),
                      *mine.value / std::max(*other.value, 1e-12),
                      other.lost > mine.lost ? " — but it lost more pairs" : "");
        notes += buf;
      }
    }
  }
  return notes;
}

/// Both tables, their captions and the notes, as Markdown.
std::string resultsMarkdown(const Manifest& manifest, const std::string& main_method) {
  const Table t1 = tableOne(manifest), t2 = tableTwo(manifest);
  std::string notes;
  if (t1.rows.count(main_method) > 0) {
    notes += notesAgainst(t1, "Table I", main_method, manifest.methods);
    notes += notesAgainst(t2, "Table II", main_method, manifest.methods);
  }
  std::string md;
  md += "### Table I — rotation RMSE [mrad], single-axis sequences\n\n";
  md += t1.markdown(manifest.methods, true, static_cast<int>(t1.columns.size()) - 1);
  md += "\nAll errors in milliradians (1 mrad = 0.057 deg; one panorama pixel = 5.7 mrad). "
        "Each scene column: RMSE over the sequence's frame pairs of the rotation-vector error "
        "about the moved axis. avg: mean over the scenes; ε: mean of the three averages (the "
        "paper's ε); 3-D angle: RMSE of the full rotation error angle over all pairs of these "
        "sequences, which also counts error on the two axes that did not move (lost pairs in "
        "parentheses); time [s]: median seconds per frame, mean over all sequences. Pairs "
        "without an estimate (lost) are not in an RMSE; their count is shown. Best value per "
        "column in bold.\n\n";
  if (!t2.columns.empty()) {
    md += "### Table II — further sequences: rotation angle RMSE [mrad], translation direction "
          "RMSE [deg]\n\n";
    md += t2.markdown(manifest.methods);
    md += "\nangle: RMSE of the rotation error angle; t-dir: RMSE of the angle between the "
          "estimated and true translation directions, degrees (the rotation-only methods "
          "estimate no translation).\n\n";
  }
  md += "### Where " + main_method + " is not ahead\n\n";
  md += notes.empty() ? main_method + " has the lowest rotation RMSE in every rotation column "
                                      "of both tables.\n"
                      : notes;
  return md;
}

constexpr const char* kUsage =
    "usage: omnipose-results MANIFEST.tsv [--main METHOD] [--out TABLES.md]";

constexpr const char* kDescription =
    "The Markdown tables of the accuracy benchmark (the paper's Table I, then\n"
    "Table II), printed and optionally written. Rotation errors are RMSE in mrad,\n"
    "translation-direction errors in degrees, time in seconds per frame.\n"
    "Exit codes: 0 written, 1 failed, 2 bad command line.";

/// The command line, as parsed.
struct Args {
  std::string manifest, out, main_method = "ifmi";
};

void addOptions(CLI::App& app, Args& a) {
  app.add_option("MANIFEST.tsv", a.manifest,
                 "one row per run, tab-separated: scene, sequence, method, GT.tum, EST.tum, "
                 "seconds_per_frame; sequence roll|pitch|yaw rows form Table I (per scene), all "
                 "others Table II")
      ->required();
  app.add_option("--main", a.main_method, "the method the notes compare against every other")
      ->type_name("METHOD")
      ->capture_default_str();
  app.add_option("--out", a.out, "also write the tables to this Markdown file")
      ->type_name("TABLES.md");
}

int run(const Args& a) {
  const std::string md = resultsMarkdown(readManifest(a.manifest), a.main_method);
  if (!a.out.empty()) {
    std::ofstream o(a.out);
    if (!o) throw std::runtime_error(a.out + ": cannot write");
    o << md;
  }
  std::fputs(md.c_str(), stdout);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  return omnipose::tools::runMain<Args>(argc, argv, {"omnipose-results", kUsage, kDescription},
                                        addOptions, [](auto&, const Args& a) { return run(a); });
}
