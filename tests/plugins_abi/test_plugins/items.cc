// Per-item test stages for the runner: items that can be made to fail (a
// marker file `<workspace>/fail-<item>`), a finalize that needs every item's
// output, a serial variant that checks it is never entered concurrently.
#include <atomic>
#include <chrono>
#include <sstream>
#include <thread>

#include "locforge/fs.h"
#include "locforge/plugin.h"

namespace {

using locforge::ParamSchema;
using locforge::RunContext;
using locforge::StageMeta;

struct ItemsOptions {
  int count = 20;           // Items listed.
  int sleep_ms = 0;         // Per-item pause, to make overlap likely.
  bool duplicate = false;   // List the first item twice (a plugin bug).
  static void Declare(ParamSchema<ItemsOptions>& s) {
    s.Add("count", &ItemsOptions::count, "Items listed").Range(0, 100000);
    s.Add("sleep_ms", &ItemsOptions::sleep_ms, "Pause per item in milliseconds").Range(0, 1000);
    s.Add("duplicate", &ItemsOptions::duplicate, "List the first item twice");
  }
};

std::string ItemName(int i) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "item_%03d", i);
  return buf;
}

class Items : public locforge::PerItemStage<ItemsOptions> {
 public:
  static StageMeta Meta() {
    return {"test", "items", "Per-item test stage (markers make items fail)", {},
            {{"items", "report", "items/<item>.txt and summary.txt"}}};
  }
  using PerItemStage::PerItemStage;

  std::vector<std::string> ListItems(RunContext&) override {
    std::vector<std::string> items;
    for (int i = options().count - 1; i >= 0; --i) items.push_back(ItemName(i));  // any order
    if (options().duplicate && !items.empty()) items.push_back(items.back());
    return items;
  }

  void ProcessItem(RunContext& ctx, const std::string& item) override {
    const int now = ++active_;
    int seen = max_active_.load();
    while (now > seen && !max_active_.compare_exchange_weak(seen, now)) {
    }
    struct Leave {
      std::atomic<int>& a;
      ~Leave() { --a; }
    } leave{active_};
    if (options().sleep_ms > 0) std::this_thread::sleep_for(std::chrono::milliseconds(options().sleep_ms));
    if (std::filesystem::exists(ctx.workspace() / ("fail-" + item)))
      throw locforge::Error("planned failure of " + item);
    uint64_t h = 1469598103934665603ull;
    for (int round = 0; round < 1000; ++round)
      for (char c : item) h = (h ^ static_cast<unsigned char>(c)) * 1099511628211ull;
    locforge::WriteFileAtomic(ctx.output_dir() / "items" / (item + ".txt"),
                              item + " " + std::to_string(h) + "\n");
    ctx.Info("processed " + item);
  }

  void Finalize(RunContext& ctx) override {
    std::string summary;
    for (int i = 0; i < options().count; ++i)  // throws if an item's output is missing
      summary += locforge::ReadFile(ctx.output_dir() / "items" / (ItemName(i) + ".txt"));
    locforge::WriteFileAtomic(ctx.output_dir() / "summary.txt", summary);
    ctx.Info("max_active " + std::to_string(max_active_.load()));
  }

 protected:
  std::atomic<int> active_{0};
  std::atomic<int> max_active_{0};
};

class SerialItems : public Items {
 public:
  static StageMeta Meta() {
    StageMeta m = Items::Meta();
    m.name = "serial_items";
    m.doc = "Like test/items, declared LF_STAGE_SERIAL_ITEMS";
    m.flags = LF_STAGE_SERIAL_ITEMS;
    return m;
  }
  using Items::Items;
  void ProcessItem(RunContext& ctx, const std::string& item) override {
    Items::ProcessItem(ctx, item);
    if (max_active_.load() > 1) throw locforge::Error("entered concurrently");
  }
};

}  // namespace

LOCFORGE_PLUGIN("lftest_items", "1.0.0", "Per-item test stages", Items, SerialItems)
