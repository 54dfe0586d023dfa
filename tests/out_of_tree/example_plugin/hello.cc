// An out-of-tree plugin with two stages, using only installed SDK headers:
//   thirdparty/text_files  writes `copies` text files holding `text`
//   thirdparty/word_count  counts the words of every *.txt of its input and
//                          writes counts.tsv (word, count; most frequent first)
//                          and counts.{svg,png} (count by rank, locforge::plot)
#include <algorithm>
#include <cctype>
#include <cstdio>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "locforge/error.h"
#include "locforge/fs.h"
#include "locforge/plot.h"
#include "locforge/plugin.h"

namespace thirdparty {

struct TextFilesOptions {
  std::string text;  // Text written into every file (required).
  int copies = 2;    // Number of files.
  static void Declare(locforge::ParamSchema<TextFilesOptions>& s) {
    s.Add("text", &TextFilesOptions::text, "Text written into every file").Required();
    s.Add("copies", &TextFilesOptions::copies, "Number of files").Range(1, 1000);
  }
};

class TextFiles : public locforge::Stage<TextFilesOptions> {
 public:
  static locforge::StageMeta Meta() {
    return {"thirdparty", "text_files", "Writes copies of a text into doc_NNN.txt files",
            {}, {{"texts", "thirdparty.texts", "folder of .txt files"}}};
  }
  using Stage::Stage;
  void Run(locforge::RunContext& ctx) override {
    for (int i = 0; i < options().copies; ++i) {
      char name[32];
      std::snprintf(name, sizeof(name), "doc_%03d.txt", i);
      locforge::WriteFileAtomic(ctx.output_dir() / name, options().text + "\n");
    }
    ctx.Info("wrote " + std::to_string(options().copies) + " files");
  }
};

struct WordCountOptions {
  int min_length = 1;           // Words shorter than this are not counted.
  bool case_sensitive = false;  // Count "The" and "the" apart.
  static void Declare(locforge::ParamSchema<WordCountOptions>& s) {
    s.Add("min_length", &WordCountOptions::min_length, "Shortest word counted").Range(1, 100);
    s.Add("case_sensitive", &WordCountOptions::case_sensitive, "Count 'The' and 'the' apart");
  }
};

class WordCount : public locforge::Stage<WordCountOptions> {
 public:
  static locforge::StageMeta Meta() {
    return {"thirdparty", "word_count", "Counts the words of every .txt file of its input",
            {{"texts", "thirdparty.texts", "folder of .txt files"}},
            {{"report", "report", "counts.tsv: word<TAB>count, most frequent first; counts.{svg,png}"}}};
  }
  using Stage::Stage;
  void Run(locforge::RunContext& ctx) override {
    const locforge::fs::path input = ctx.Input("texts");
    std::vector<locforge::fs::path> files;
    for (const auto& entry : locforge::fs::directory_iterator(input))
      if (entry.is_regular_file() && entry.path().extension() == ".txt")
        files.push_back(entry.path());
    std::sort(files.begin(), files.end());
    if (files.empty())
      throw locforge::InputError(input.string(), 0, "", "no .txt file to count");

    std::map<std::string, long> counts;
    long total = 0;
    for (const auto& file : files) {
      std::istringstream words(locforge::ReadFile(file));
      for (std::string word; words >> word;) {
        if (static_cast<int>(word.size()) < options().min_length) continue;
        if (!options().case_sensitive)
          for (char& c : word) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
        ++counts[word];
        ++total;
      }
    }
    std::vector<std::pair<std::string, long>> sorted(counts.begin(), counts.end());
    std::stable_sort(sorted.begin(), sorted.end(),
                     [](const auto& a, const auto& b) { return a.second > b.second; });
    std::string report;
    for (const auto& [word, n] : sorted) report += word + "\t" + std::to_string(n) + "\n";
    report += "total\t" + std::to_string(total) + "\n";
    locforge::WriteFileAtomic(ctx.output_dir() / "counts.tsv", report);

    locforge::plot::Figure figure;
    figure.title = "Words by rank";
    figure.x_label = "rank";
    figure.y_label = "count";
    figure.series.push_back({"words", {}, {}, "", true});
    for (size_t i = 0; i < sorted.size(); ++i) {
      figure.series[0].x.push_back(static_cast<double>(i + 1));
      figure.series[0].y.push_back(static_cast<double>(sorted[i].second));
    }
    for (const char* extension : {".svg", ".png"})
      locforge::plot::WriteFigure(figure, (ctx.output_dir() / "counts").string() + extension);
  }
};

}  // namespace thirdparty

LOCFORGE_PLUGIN("hello_plugin", "0.4.0", "Out-of-tree example: text files and word counts",
                thirdparty::TextFiles, thirdparty::WordCount)
