#include "query_results.h"

#include <sstream>

#include "locforge/error.h"
#include "locforge/kapture/csv.h"
#include "locforge/kapture/io.h"

namespace locforge::localization {

namespace kp = locforge::kapture;

fs::path QueryResultFile(const fs::path& output_dir, const std::string& item) {
  return SafeJoin(output_dir / "results", item + ".txt");
}

// Format: line 1 "ok qw qx qy qz tx ty tz" or "failed <reason>"; line 2 the
// stats separated by spaces.
void WriteQueryResult(const fs::path& output_dir, const std::string& item,
                      const QueryOutcome& outcome) {
  std::ostringstream out;
  out.precision(17);
  if (outcome.success) {
    const Pose& p = outcome.device_from_world;
    out << "ok " << p.q.w() << " " << p.q.x() << " " << p.q.y() << " " << p.q.z() << " "
        << p.t.x() << " " << p.t.y() << " " << p.t.z();
  } else {
    std::string reason = outcome.failure;
    for (char& c : reason) c = c == '\n' ? ' ' : c;
    out << "failed " << reason;
  }
  out << "\n";
  for (size_t i = 0; i < outcome.stats.size(); ++i) out << (i ? " " : "") << outcome.stats[i];
  out << "\n";
  WriteFileAtomic(QueryResultFile(output_dir, item), out.str());
}

QueryOutcome ReadQueryResult(const fs::path& output_dir, const std::string& item,
                             size_t stat_count) {
  const fs::path file = QueryResultFile(output_dir, item);
  std::istringstream in(ReadFile(file));
  std::string first, second;
  std::getline(in, first);
  std::getline(in, second);
  QueryOutcome o;
  auto words = [](const std::string& line) {
    std::vector<std::string> w;
    std::istringstream s(line);
    for (std::string x; s >> x;) w.push_back(x);
    return w;
  };
  const std::vector<std::string> head = words(first);
  if (!head.empty() && head[0] == "ok") {
    if (head.size() != 8) throw InputError(file.string(), 1, "pose", "expected ok + 7 numbers");
    double v[7];
    for (int i = 0; i < 7; ++i) v[i] = kp::ParseDouble(head[i + 1], file.string(), 1, "pose");
    o.success = true;
    o.device_from_world = Pose(Eigen::Quaterniond(v[0], v[1], v[2], v[3]), {v[4], v[5], v[6]});
  } else if (!head.empty() && head[0] == "failed") {
    o.failure = first.size() > 7 ? first.substr(7) : "";
  } else {
    throw InputError(file.string(), 1, "status", "expected 'ok' or 'failed'");
  }
  for (const std::string& w : words(second)) o.stats.push_back(kp::ParseDouble(w, file.string(), 2, "stats"));
  if (o.stats.size() != stat_count)
    throw InputError(file.string(), 2, "stats", std::to_string(o.stats.size()) + " values, expected " +
                                                    std::to_string(stat_count));
  return o;
}

int WriteLocalizationOutputs(const fs::path& output_dir, const std::vector<QueryItemInfo>& items,
                             const std::vector<std::string>& stat_names,
                             const kp::Sensors& sensors, const kp::Rigs& rigs) {
  kp::Trajectories trajectories;
  std::ostringstream failures, stats;
  stats.precision(10);
  failures << "# item, timestamp, device_id, reason\n";
  stats << "item,status";
  for (const std::string& s : stat_names) stats << "," << s;
  stats << "\n";
  int ok = 0;
  for (const QueryItemInfo& item : items) {
    const QueryOutcome o = ReadQueryResult(output_dir, item.name, stat_names.size());
    if (o.success) {
      trajectories.Set(item.timestamp, item.device, o.device_from_world);
      ++ok;
    } else {
      failures << item.name << ", " << item.timestamp << ", " << item.device << ", " << o.failure << "\n";
    }
    stats << item.name << "," << (o.success ? "ok" : "failed");
    for (double v : o.stats) stats << "," << v;
    stats << "\n";
  }
  fs::create_directories(output_dir / "sensors");
  kp::WriteSensors(output_dir / kp::layout::kSensors, sensors);
  if (!rigs.empty()) kp::WriteRigs(output_dir / kp::layout::kRigs, rigs);
  kp::WriteTrajectories(output_dir / kp::layout::kTrajectories, trajectories);
  WriteFileAtomic(output_dir / "failures.txt", failures.str());
  WriteFileAtomic(output_dir / "localization_stats.csv", stats.str());
  return ok;
}

}  // namespace locforge::localization
