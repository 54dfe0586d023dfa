// kapture text files: the line/field reader shared by every kapture parser,
// field conversion with clear errors, and the toolbox's number formatting.
//
// Syntax accepted (that of the kapture toolbox, kapture/io/csv.py):
//  - one record per line; fields separated by ',' with any spaces or tabs
//    around them ("a,b", "a, b", "a ,  b" are the same); leading/trailing
//    blanks of a field are dropped; empty fields are kept ("id, , camera");
//  - lines whose first non-blank character is '#' are comments; the first
//    one may be the version header "# kapture format: 1.1";
//  - blank lines are skipped; "\n", "\r\n" and a missing final newline are
//    all fine;
//  - no quoting: the toolbox has none, so '"' is an ordinary character and a
//    field can never contain ','.
#ifndef LOCFORGE_KAPTURE_CSV_H_
#define LOCFORGE_KAPTURE_CSV_H_

#include <cstdint>
#include <fstream>
#include <istream>
#include <memory>
#include <string>
#include <vector>

#include "locforge/fs.h"

namespace locforge::kapture {

// The version this SDK writes, and the header line that states it.
inline constexpr const char* kKaptureVersion = "1.1";
inline constexpr const char* kKaptureVersionHeader = "# kapture format: 1.1";

// One data line of a kapture text file.
struct CsvRow {
  int64_t line = 0;                 // 1-based line number in the file
  std::vector<std::string> fields;  // trimmed fields, empty ones kept
};

// Reads a kapture text file line by line: memory stays O(one line), so
// records files of any size can be streamed.
class CsvReader {
 public:
  // Opens `path`; `display_name` (e.g. "sensors/trajectories.txt") is what
  // error messages name; empty -> path.string(). Throws InputError when the
  // file cannot be opened.
  explicit CsvReader(const fs::path& path, std::string display_name = "");
  // Reads from a stream the caller keeps alive (in-memory parsing, fuzzing).
  CsvReader(std::istream& in, std::string display_name);

  // The next data line, skipping comments and blank lines. False at the end.
  bool Next(CsvRow* row);

  const std::string& name() const { return name_; }
  // Version from a "# kapture format: X" header seen so far ("" if none).
  const std::string& version() const { return version_; }
  // The first 16 comment lines seen so far, without the leading '#' and
  // blanks (the column header of a records file is among these).
  const std::vector<std::string>& comments() const { return comments_; }

 private:
  std::unique_ptr<std::ifstream> owned_;
  std::istream* in_ = nullptr;
  std::string name_;
  std::string version_;
  std::vector<std::string> comments_;
  std::string buffer_;
  int64_t line_ = 0;
};

// Splits one line the toolbox's way (see the top of this file).
std::vector<std::string> SplitCsvLine(const std::string& line);

// Field conversion. Each throws InputError naming file, line and field:
// "sensors/trajectories.txt:12: field 'qw': expected a number, got 'abc'".
// Numbers are parsed with the C locale; "nan"/"inf" are accepted by
// ParseDouble like Python's float().
double ParseDouble(const std::string& text, const std::string& file, int64_t line,
                   const std::string& field);
int64_t ParseInt64(const std::string& text, const std::string& file, int64_t line,
                   const std::string& field);
// Throws unless row.fields.size() is in [min_fields, max_fields]
// (max_fields < 0: no upper bound); `columns` names them for the message.
void CheckFieldCount(const CsvRow& row, const std::string& file, size_t min_fields,
                     int64_t max_fields, const std::string& columns);

// Python's repr(float), which the toolbox writes: shortest text that reads
// back to the same double ("0.1", "1.0", "2.7755575615628914e-17", "1e-05",
// "-0.0", "nan", "inf").
std::string FormatDouble(double value);
// numpy.savetxt's default "%.18e" (points3d.txt).
std::string FormatDoubleSavetxt(double value);

// Joins fields with ", " as the toolbox does.
std::string JoinCsv(const std::vector<std::string>& fields);

}  // namespace locforge::kapture

#endif  // LOCFORGE_KAPTURE_CSV_H_
