#include "locforge/kapture/csv.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <sstream>

#include "locforge/error.h"
#include "locforge/kapture/io.h"

namespace locforge::kapture {
namespace {

TEST(FormatDouble, MatchesPythonRepr) {
  // Expected strings are what CPython's repr(float) prints.
  EXPECT_EQ(FormatDouble(0.0), "0.0");
  EXPECT_EQ(FormatDouble(-0.0), "-0.0");
  EXPECT_EQ(FormatDouble(1.0), "1.0");
  EXPECT_EQ(FormatDouble(-0.1), "-0.1");
  EXPECT_EQ(FormatDouble(280.0), "280.0");
  EXPECT_EQ(FormatDouble(0.0001), "0.0001");
  EXPECT_EQ(FormatDouble(1e-05), "1e-05");
  EXPECT_EQ(FormatDouble(2.7755575615628914e-17), "2.7755575615628914e-17");
  EXPECT_EQ(FormatDouble(-2.220446049250313e-16), "-2.220446049250313e-16");
  EXPECT_EQ(FormatDouble(1e15), "1000000000000000.0");
  EXPECT_EQ(FormatDouble(1e16), "1e+16");
  EXPECT_EQ(FormatDouble(1.5e16), "1.5e+16");
  EXPECT_EQ(FormatDouble(123456789.125), "123456789.125");
  EXPECT_EQ(FormatDouble(488.0082384493067), "488.0082384493067");
  EXPECT_EQ(FormatDouble(1.9543209999999998), "1.9543209999999998");
  EXPECT_EQ(FormatDouble(8.64655776076572e-07), "8.64655776076572e-07");
  EXPECT_EQ(FormatDouble(std::numeric_limits<double>::infinity()), "inf");
  EXPECT_EQ(FormatDouble(-std::numeric_limits<double>::infinity()), "-inf");
  EXPECT_EQ(FormatDouble(std::nan("")), "nan");
  EXPECT_EQ(FormatDouble(5e-324), "5e-324");
  EXPECT_EQ(FormatDouble(1.7976931348623157e308), "1.7976931348623157e+308");
}

TEST(FormatDouble, RoundTripsRandomDoubles) {
  std::mt19937_64 rng(7);
  for (int i = 0; i < 20000; ++i) {
    const uint64_t bits = rng();
    double v;
    std::memcpy(&v, &bits, sizeof(v));
    if (!std::isfinite(v)) continue;
    const std::string s = FormatDouble(v);
    const double back = ParseDouble(s, "x", 1, "v");
    ASSERT_EQ(std::memcmp(&v, &back, sizeof(v)), 0) << s;
  }
}

TEST(FormatDoubleSavetxt, MatchesNumpy) {
  EXPECT_EQ(FormatDoubleSavetxt(57.0), "5.700000000000000000e+01");
  EXPECT_EQ(FormatDoubleSavetxt(-2.39675), "-2.396749999999999936e+00");
}

TEST(SplitCsvLine, ToolboxSpacingVariants) {
  EXPECT_EQ(SplitCsvLine("a,b"), (std::vector<std::string>{"a", "b"}));
  EXPECT_EQ(SplitCsvLine("a, b"), (std::vector<std::string>{"a", "b"}));
  EXPECT_EQ(SplitCsvLine("  a ,\tb  ,c\r"), (std::vector<std::string>{"a", "b", "c"}));
  EXPECT_EQ(SplitCsvLine("id, , camera"), (std::vector<std::string>{"id", "", "camera"}));
  EXPECT_EQ(SplitCsvLine("-59 ,"), (std::vector<std::string>{"-59", ""}));
  // No quoting in kapture: quotes are ordinary characters.
  EXPECT_EQ(SplitCsvLine("\"a\", b"), (std::vector<std::string>{"\"a\"", "b"}));
}

TEST(CsvReader, CommentsBlankLinesCrlfAndVersion) {
  std::istringstream in(
      "# kapture format: 1.1\r\n# timestamp, device_id, image_path\r\n\r\n   \n"
      "1, cam, a.jpg\r\n  # indented comment\n2,cam,b.jpg");
  CsvReader csv(in, "records_camera.txt");
  CsvRow row;
  ASSERT_TRUE(csv.Next(&row));
  EXPECT_EQ(row.line, 5);
  EXPECT_EQ(row.fields, (std::vector<std::string>{"1", "cam", "a.jpg"}));
  ASSERT_TRUE(csv.Next(&row));
  EXPECT_EQ(row.line, 7);
  EXPECT_EQ(row.fields, (std::vector<std::string>{"2", "cam", "b.jpg"}));
  EXPECT_FALSE(csv.Next(&row));
  EXPECT_EQ(csv.version(), "1.1");
}

TEST(ParseDouble, NamesFileLineAndField) {
  try {
    ParseDouble("abc", "sensors/trajectories.txt", 12, "qw");
    FAIL() << "no throw";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "sensors/trajectories.txt:12: field 'qw': expected a number, got 'abc'");
  }
  EXPECT_THROW(ParseDouble("", "f", 1, "x"), InputError);
  EXPECT_THROW(ParseDouble("1.0.0", "f", 1, "x"), InputError);
  EXPECT_THROW(ParseDouble("0x10", "f", 1, "x"), InputError);
  EXPECT_DOUBLE_EQ(ParseDouble("+1.5e3", "f", 1, "x"), 1500.0);
  EXPECT_TRUE(std::isinf(ParseDouble("-inf", "f", 1, "x")));
  EXPECT_TRUE(std::isnan(ParseDouble("nan", "f", 1, "x")));
  EXPECT_TRUE(std::isinf(ParseDouble("1e999", "f", 1, "x")));
}

TEST(ParseInt64, RefusesFloatsAndOverflow) {
  EXPECT_EQ(ParseInt64("1555399760151000", "f", 1, "timestamp"), 1555399760151000);
  EXPECT_THROW(ParseInt64("1.5", "f", 1, "timestamp"), InputError);
  EXPECT_THROW(ParseInt64("99999999999999999999", "f", 1, "timestamp"), InputError);
}

TEST(Trajectories, WrongColumnCountIsNamed) {
  std::istringstream in("# kapture format: 1.1\n1, cam, 1, 0, 0, 0, 0, 0\n");
  try {
    ParseTrajectories(in, "sensors/trajectories.txt");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("sensors/trajectories.txt:2"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("expected 9 fields"), std::string::npos) << e.what();
  }
}

TEST(Trajectories, PartialPosesRoundTrip) {
  std::istringstream in(
      "1, cam, 1, 0, 0, 0, , , \n"
      "2, cam, , , , , 1, 2, 3\n"
      "3, cam, 0.5, 0.5, 0.5, 0.5, 4, 5, 6\n");
  const Trajectories t = ParseTrajectories(in, "t.txt");
  ASSERT_EQ(t.size(), 3u);
  EXPECT_EQ(t.PartsOf({1, "cam"}), PoseParts::kRotationOnly);
  EXPECT_EQ(t.PartsOf({2, "cam"}), PoseParts::kTranslationOnly);
  EXPECT_EQ(t.PartsOf({3, "cam"}), PoseParts::kComplete);
  EXPECT_EQ(FormatPoseFields(t.poses.at({1, "cam"}), PoseParts::kRotationOnly),
            (std::vector<std::string>{"1.0", "0.0", "0.0", "0.0", "", "", ""}));
  EXPECT_EQ(FormatPoseFields(t.poses.at({2, "cam"}), PoseParts::kTranslationOnly),
            (std::vector<std::string>{"", "", "", "", "1.0", "2.0", "3.0"}));
  std::istringstream half("1, cam, 1, , 0, 0, 1, 2, 3\n");
  try {
    ParseTrajectories(half, "t.txt");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "t.txt:1: field 'qx': empty while other fields of the rotation are set");
  }
}

TEST(Sensors, CameraModelsAndUnknownTypesKeptVerbatim) {
  std::istringstream in(
      "# kapture format: 1.1\n"
      "cam0, front, camera, OPENCV, 640, 480, 500, 501, 320, 240, 0.1, -0.01, 0.001, 0.002\n"
      "cam1, , camera, UNKNOWN_CAMERA, 640, 480, whatever\n"
      "dev, , depth, SIMPLE_PINHOLE, 640, 480, 585, 320, 240\n"
      "gps, , gnss, EPSG:4326\n"
      "baro, pressure, barometer, hPa, 42\n");
  const Sensors s = ParseSensors(in, "sensors.txt");
  ASSERT_EQ(s.size(), 5u);
  const Sensor* cam0 = s.Find("cam0");
  ASSERT_TRUE(cam0 && cam0->camera);
  EXPECT_EQ(cam0->camera->model, CameraModelId::kOpenCV);
  EXPECT_EQ(cam0->camera->width, 640);
  EXPECT_DOUBLE_EQ(cam0->camera->params[1], 501.0);
  EXPECT_EQ(s.Find("cam1")->camera->model, CameraModelId::kUnknown);
  EXPECT_EQ(s.Find("cam1")->params.back(), "whatever");
  EXPECT_EQ(s.Find("dev")->camera->model, CameraModelId::kSimplePinhole);
  EXPECT_EQ(s.Find("gps")->EpsgCode(), "EPSG:4326");
  EXPECT_EQ(s.Find("baro")->type, "barometer");
  EXPECT_EQ(s.Find("baro")->params, (std::vector<std::string>{"hPa", "42"}));

  std::istringstream bad("cam, , camera, PINHOLE, 640, 480, 500, 500, 320\n");
  try {
    ParseSensors(bad, "sensors/sensors.txt");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("sensors/sensors.txt:1: field 'sensor_params'"),
              std::string::npos)
        << e.what();
  }
  std::istringstream bad_model("cam, , camera, FISHEYE_9000, 640, 480\n");
  EXPECT_THROW(ParseSensors(bad_model, "s"), InputError);
  std::istringstream dup("a, , lidar\na, , wifi\n");
  EXPECT_THROW(ParseSensors(dup, "s"), InputError);
}

TEST(Sensors, MakeCameraSensorFormatsLikeTheToolbox) {
  Camera cam;
  cam.model = CameraModelId::kPinhole;
  cam.width = 1920;
  cam.height = 1080;
  cam.params = {1371.022, 1371.022, 959.5, 539.5};
  const Sensor s = MakeCameraSensor("training_camera_0", "", cam);
  EXPECT_EQ(JoinCsv(s.params), "PINHOLE, 1920, 1080, 1371.022, 1371.022, 959.5, 539.5");
  cam.params.pop_back();
  EXPECT_THROW(MakeCameraSensor("c", "", cam), ParamError);
}

TEST(Observations, Reads11And10Forms) {
  std::istringstream v11("# kapture format: 1.1\n0, SIFT, 01.jpg, 4561, 02.jpg, 3389\n");
  const Observations a = ParseObservations(v11, "o");
  ASSERT_EQ(a.size(), 1u);
  EXPECT_EQ(a[0].keypoints_type, "SIFT");
  EXPECT_EQ(a[0].features[1], (std::pair<std::string, int64_t>("02.jpg", 3389)));
  std::istringstream v10("# kapture format: 1.0\n0, 01.jpg, 4561, 02.jpg, 3389\n");
  const Observations b = ParseObservations(v10, "o", "sift");
  ASSERT_EQ(b.size(), 1u);
  EXPECT_EQ(b[0].keypoints_type, "sift");
  EXPECT_EQ(b[0].features.size(), 2u);
  std::istringstream odd("# kapture format: 1.1\n0, SIFT, 01.jpg\n");
  EXPECT_THROW(ParseObservations(odd, "o"), InputError);
}

TEST(Records, WifiAndBluetooth11Columns) {
  std::istringstream wifi(
      "1555398770307, AC01324954_wifi, 68:72:51:80:52:df, 2417     ,-33.0, M1X_PicoM2    , 0 , \n");
  RecordsReader<WifiRecord> r(wifi, "records_wifi.txt");
  WifiRecord w;
  ASSERT_TRUE(r.Next(&w));
  EXPECT_EQ(w.bssid, "68:72:51:80:52:df");
  EXPECT_EQ(w.frequency, 2417);
  EXPECT_EQ(w.rssi, -33.0);
  EXPECT_EQ(w.ssid, "M1X_PicoM2");
  EXPECT_EQ(w.scan_time_start, 0);
  EXPECT_FALSE(w.scan_time_end.has_value());
  std::istringstream bt("1, dev, 35:A8:4B:D9:95:06, -73 ,\n2, dev, 6F:80:17:51:5C:16, -88 ,MyPhone");
  RecordsReader<BluetoothRecord> b(bt, "records_bluetooth.txt");
  BluetoothRecord x;
  ASSERT_TRUE(b.Next(&x));
  EXPECT_EQ(x.name, "");
  EXPECT_EQ(x.rssi, -73.0);
  ASSERT_TRUE(b.Next(&x));
  EXPECT_EQ(x.name, "MyPhone");
  EXPECT_FALSE(b.Next(&x));
}

}  // namespace
}  // namespace locforge::kapture
