// `locforge colmap export ...` and `locforge colmap import ...`: kapture <->
// COLMAP 3.8 (database + sparse model), see locforge/colmap/convert.h.
#include <iostream>
#include <stdexcept>

#include "cli.h"
#include "locforge/colmap/convert.h"
#include "locforge/error.h"
#include "locforge/kapture/kapture.h"

namespace locforge::host {

namespace {

const char kColmapHelp[] =
    "Usage: locforge colmap export KAPTURE_DIR --database DB [--model DIR] [--text|--binary]\n"
    "                              [--keypoints TYPE] [--descriptors TYPE] [--no-points]\n"
    "                              [--no-two-view-geometries] [--overwrite]\n"
    "       locforge colmap import --database DB [--model DIR] KAPTURE_OUT\n"
    "                              [--features-type NAME] [--raw-matches] [--overwrite]\n"
    "\n"
    "Converts between kapture 1.1 and COLMAP 3.8 (SQLite database + sparse model).\n"
    "Poses are world-to-camera in both (rig poses are composed per camera on export);\n"
    "keypoint coordinates pass unchanged (both put the first pixel centre at 0.5, 0.5).\n"
    "camera_id/image_id are 1 + the rank of the sorted sensor id / image name.\n"
    "\n"
    "  export KAPTURE_DIR   Writes the COLMAP database DB (cameras, images with pose\n"
    "                       priors, keypoints, uint8 descriptors, matches, and the\n"
    "                       matches as two-view geometries) and, with --model, the\n"
    "                       sparse model of the posed images with points3D and tracks\n"
    "                       from points3d.txt + observations.txt.\n"
    "      --database DB          database file to create (required)\n"
    "      --model DIR            also write cameras/images/points3D here\n"
    "      --text | --binary      model format (default --text)\n"
    "      --keypoints TYPE       keypoints type (default: the only one present)\n"
    "      --descriptors TYPE     descriptors type (default: the one of the keypoints)\n"
    "      --no-points            point-less model (input of colmap point_triangulator)\n"
    "      --no-two-view-geometries  leave the two_view_geometries table empty\n"
    "      --overwrite            replace an existing database\n"
    "\n"
    "  import KAPTURE_OUT   Writes a kapture from the database and/or model: cameras\n"
    "                       (refined ones from the model), images, poses, keypoints,\n"
    "                       descriptors, matches (verified ones from two_view_geometries\n"
    "                       when present), points3d + observations. Sensors are named\n"
    "                       cam_%05d after the camera_id, timestamps are image ids.\n"
    "      --database DB          COLMAP database to read\n"
    "      --model DIR            COLMAP sparse model to read (.bin or .txt)\n"
    "      --features-type NAME   kapture keypoints/descriptors type (default SIFT)\n"
    "      --raw-matches          import the `matches` table, not the verified inliers\n"
    "      --overwrite            allow a KAPTURE_OUT folder that is not empty\n"
    "\n"
    "Exit status: 0 done, 1 the work failed, 2 bad usage or bad input (the message\n"
    "names the file, line and field).\n";

void PrintNotes(const std::vector<std::string>& notes) {
  for (const std::string& n : notes) std::cout << "  note: " << n << "\n";
}

int Export(const Args& args) {
  std::vector<std::string> positional;
  std::string database, model;
  colmap::ExportOptions options;
  for (size_t i = 0; i < args.size(); ++i) {
    std::string value;
    const std::string& a = args[i];
    if (TakeOption(args, &i, "--database", &database) || TakeOption(args, &i, "--model", &model)) {
      continue;
    } else if (TakeOption(args, &i, "--keypoints", &value)) {
      options.keypoints_type = value;
    } else if (TakeOption(args, &i, "--descriptors", &value)) {
      options.descriptors_type = value;
    } else if (a == "--text") {
      options.model_format = colmap::ModelFormat::kText;
    } else if (a == "--binary") {
      options.model_format = colmap::ModelFormat::kBinary;
    } else if (a == "--no-points") {
      options.export_points3d = false;
    } else if (a == "--no-two-view-geometries") {
      options.export_two_view_geometries = false;
    } else if (a == "--overwrite") {
      options.overwrite = true;
    } else if (a.rfind("--", 0) == 0) {
      return UsageError("colmap", "unknown option '" + a + "' for export");
    } else {
      positional.push_back(a);
    }
  }
  if (positional.size() != 1) return UsageError("colmap", "export takes one KAPTURE_DIR");
  if (database.empty()) return UsageError("colmap", "export needs --database DB");
  std::error_code ec;
  if (!fs::is_directory(positional[0], ec)) {
    return UsageError("colmap", "'" + positional[0] + "' is not a folder");
  }
  const kapture::Kapture k(positional[0]);
  const colmap::ExportReport r = colmap::ExportToColmap(k, database, model, options);
  std::cout << "exported " << positional[0] << " -> " << database
            << (model.empty() ? "" : " + " + model) << ": " << r.cameras << " cameras, "
            << r.images << " images (" << r.posed_images << " posed), keypoints '"
            << r.keypoints_type << "' for " << r.keypoint_images << " images, descriptors for "
            << r.descriptor_images << ", " << r.match_pairs << " matched pairs (" << r.matches
            << " matches), " << r.points3d << " points3D (" << r.observations
            << " observations, mean reprojection error " << r.mean_reprojection_error
            << " px)\n";
  PrintNotes(r.notes);
  return 0;
}

int Import(const Args& args) {
  std::vector<std::string> positional;
  std::string database, model, value;
  colmap::ImportOptions options;
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    if (TakeOption(args, &i, "--database", &database) || TakeOption(args, &i, "--model", &model)) {
      continue;
    } else if (TakeOption(args, &i, "--features-type", &value)) {
      options.features_type = value;
    } else if (a == "--raw-matches") {
      options.verified_matches = false;
    } else if (a == "--overwrite") {
      options.overwrite = true;
    } else if (a.rfind("--", 0) == 0) {
      return UsageError("colmap", "unknown option '" + a + "' for import");
    } else {
      positional.push_back(a);
    }
  }
  if (positional.size() != 1) return UsageError("colmap", "import takes one KAPTURE_OUT");
  if (database.empty() && model.empty()) {
    return UsageError("colmap", "import needs --database DB and/or --model DIR");
  }
  const colmap::ImportReport r =
      colmap::ImportFromColmap(database, model, positional[0], options);
  std::cout << "imported " << (database.empty() ? "" : database)
            << (database.empty() || model.empty() ? "" : " + ") << model << " -> "
            << positional[0] << ": " << r.cameras << " cameras, " << r.images << " images ("
            << r.posed_images << " posed), keypoints for " << r.keypoint_images
            << " images, descriptors for " << r.descriptor_images << ", " << r.match_pairs
            << " matched pairs, " << r.points3d << " points3d (" << r.observations
            << " observations)\n";
  PrintNotes(r.notes);
  return 0;
}

}  // namespace

int ColmapCommand(const Args& args) {
  if (args.empty()) return UsageError("colmap", "missing subcommand (export or import)");
  if (WantsHelp(args) || args[0] == "help") {
    std::cout << kColmapHelp;
    return 0;
  }
  const std::string sub = args[0];
  const Args rest(args.begin() + 1, args.end());
  try {
    if (sub == "export") return Export(rest);
    if (sub == "import") return Import(rest);
    return UsageError("colmap", "unknown subcommand '" + sub + "' (export or import)");
  } catch (const std::invalid_argument& e) {  // an option without its value
    return UsageError("colmap", e.what());
  } catch (const InputError& e) {
    std::cerr << "locforge colmap " << sub << ": " << e.what() << "\n";
    return 2;
  } catch (const ParamError& e) {
    std::cerr << "locforge colmap " << sub << ": " << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "locforge colmap " << sub << ": error: " << e.what() << "\n";
    return 1;
  }
}

}  // namespace locforge::host
