#include "text_parsers.h"

#include <sstream>
#include <string>

#include "locforge/error.h"
#include "locforge/kapture/io.h"

namespace locforge::kapture::internal {

namespace {

template <class Fn>
int Try(Fn&& fn) {
  try {
    fn();
    return 1;
  } catch (const locforge::Error&) {
    return 0;
  }
}

template <class Record>
void StreamAll(const std::string& text, const char* name) {
  std::istringstream in(text);
  RecordsReader<Record> reader(in, name);
  Record r;
  while (reader.Next(&r)) {
  }
  (void)reader.ColumnsComment();
}

}  // namespace

int RunAllTextParsers(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  int ok = 0;
  auto stream = [&text]() { return std::istringstream(text); };
  ok += Try([&] { auto in = stream(); ParseSensors(in, "sensors.txt"); });
  ok += Try([&] { auto in = stream(); ParseRigs(in, "rigs.txt"); });
  ok += Try([&] { auto in = stream(); ParseTrajectories(in, "trajectories.txt"); });
  ok += Try([&] { StreamAll<DataRecord>(text, "records_camera.txt"); });
  ok += Try([&] { StreamAll<GnssRecord>(text, "records_gnss.txt"); });
  ok += Try([&] { StreamAll<WifiRecord>(text, "records_wifi.txt"); });
  ok += Try([&] { StreamAll<BluetoothRecord>(text, "records_bluetooth.txt"); });
  ok += Try([&] { StreamAll<Vector3Record>(text, "records_gyroscope.txt"); });
  ok += Try([&] { StreamAll<GenericRecord>(text, "records_other.txt"); });
  for (FeatureKind kind :
       {FeatureKind::kKeypoints, FeatureKind::kDescriptors, FeatureKind::kGlobalFeatures})
    ok += Try([&] { auto in = stream(); ParseFeatureInfo(in, kind, "features.txt"); });
  ok += Try([&] { auto in = stream(); ParsePoints3d(in, "points3d.txt"); });
  ok += Try([&] { auto in = stream(); ParseObservations(in, "observations.txt"); });
  return ok;
}

}  // namespace locforge::kapture::internal
