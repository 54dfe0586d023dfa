// Localization scoring as in the paper (section 4): position error of camera
// centres, geodesic rotation error, recall at (position, angle) thresholds
// with <= bounds, unlocalized queries counted as failures; tables as
// Markdown/CSV/LaTeX and a recall curve (Figure 7) as SVG and PNG.
#ifndef LOCFORGE_PLUGINS_EVAL_LOCALIZATION_EVALUATION_H_
#define LOCFORGE_PLUGINS_EVAL_LOCALIZATION_EVALUATION_H_

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "locforge/plot.h"
#include "locforge/pose.h"

namespace locforge::evaluation {

// Figure 7 of the paper: angle threshold (deg) = 10 x position threshold (m).
inline constexpr double kAnglePerMetre = 10;

struct QueryError {
  std::string image;
  std::string device;
  std::string group;  // camera group label ("" when no groups)
  std::string split;  // split label ("" when no splits)
  bool localized = false;
  double position_m = 0;     // |C_est - C_gt|, when localized
  double rotation_deg = 0;   // geodesic angle, when localized
};

// Errors of an estimated world-to-camera pose against the ground truth one.
QueryError ComputeError(const Pose& ground_truth, const std::optional<Pose>& estimate);

struct Threshold {
  double position_m = 0;
  double rotation_deg = 0;
};

// Fraction (0..1) of `errors` localized with position <= t.position_m and
// rotation <= t.rotation_deg; unlocalized ones count as failures. 0 when empty.
double Recall(const std::vector<QueryError>& errors, const Threshold& t);

// Median of the localized errors (NaN when none).
double MedianPosition(const std::vector<QueryError>& errors);
double MedianRotation(const std::vector<QueryError>& errors);

// A plain table: header + rows of already formatted cells.
struct Table {
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;
};
std::string ToMarkdown(const Table& table);
std::string ToCsv(const Table& table);    // RFC 4180 quoting when needed
std::string ToLatex(const Table& table);  // tabular, special characters escaped
// Parses ToCsv's output back (quoted fields, doubled quotes).
Table FromCsv(const std::string& text, const std::string& file_name);

// The method label of an eval/localization report folder: the first row of
// its summary.csv, else the folder's name.
std::string ReportMethod(const std::filesystem::path& report);

// Figure 7's curve: recall (%) with both thresholds varying together,
// position p in [0, max_position_m] over `steps` intervals and angle
// threshold = angle_per_m x p (the paper: 10 deg per metre, 1 deg per 10 cm).
// With log_decades > 0, p runs geometrically over that many decades below
// max_position_m instead (even steps on RecallFigure's log axis).
plot::Series RecallCurve(const std::vector<QueryError>& errors, const std::string& label,
                         double max_position_m, double angle_per_m = 10, int steps = 100,
                         double log_decades = 0);
// Decades of position threshold a recall figure shows: 1 mm to 1 m for the
// default 1 m, so millimetre ground truth and metre failures both show.
constexpr double kRecallDecades = 3;
// The curves of one or several methods as a figure (SVG or PNG via
// plot::WriteFigure): recall against the position threshold on a log axis
// over kRecallDecades below max_position_m.
plot::Figure RecallFigure(std::vector<plot::Series> curves, const std::string& title,
                          double max_position_m, double angle_per_m = 10);

// Percentage with one decimal ("62.5").
std::string Percent(double fraction);

}  // namespace locforge::evaluation

#endif  // LOCFORGE_PLUGINS_EVAL_LOCALIZATION_EVALUATION_H_
