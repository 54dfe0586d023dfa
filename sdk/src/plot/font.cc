#include "font.h"

#include <cairo-ft.h>
#include <fontconfig/fontconfig.h>
#include <ft2build.h>
#include FT_FREETYPE_H

#include <memory>
#include <mutex>

#include "locforge/error.h"

namespace locforge::plot::internal {
namespace {

// The face is made from the font file directly (not through Cairo's toy API,
// which applies the machine's fontconfig rules): the output then depends only
// on the file and the options SetFont fixes.
struct LoadedFont {
  std::string file;
  cairo_font_face_t* face = nullptr;  // lives as long as the process
  std::string error;
};

std::string MatchFontFile(const char* name, std::string* family) {
  FcPattern* pattern = FcNameParse(reinterpret_cast<const FcChar8*>(name));
  if (!pattern) return "";
  FcConfigSubstitute(nullptr, pattern, FcMatchPattern);
  FcDefaultSubstitute(pattern);
  FcResult result = FcResultNoMatch;
  FcPattern* match = FcFontMatch(nullptr, pattern, &result);
  FcPatternDestroy(pattern);
  std::string file;
  if (match) {
    FcChar8* value = nullptr;
    if (FcPatternGetString(match, FC_FILE, 0, &value) == FcResultMatch) {
      file = reinterpret_cast<const char*>(value);
    }
    if (FcPatternGetString(match, FC_FAMILY, 0, &value) == FcResultMatch) {
      *family = reinterpret_cast<const char*>(value);
    }
    FcPatternDestroy(match);
  }
  return file;
}

LoadedFont Load() {
  LoadedFont font;
  if (!FcInit()) {
    font.error = "fontconfig could not be initialised";
    return font;
  }
  std::string family;
  font.file = MatchFontFile("DejaVu Sans:style=Book", &family);
  if (family != "DejaVu Sans") {
    const std::string fallback = MatchFontFile("sans-serif", &family);
    if (!fallback.empty()) font.file = fallback;
  }
  if (font.file.empty()) {
    font.error = "no font found for plots (install fonts-dejavu-core)";
    return font;
  }
  FT_Library library = nullptr;
  FT_Face ft_face = nullptr;
  if (FT_Init_FreeType(&library) != 0 || FT_New_Face(library, font.file.c_str(), 0, &ft_face) != 0) {
    font.error = "cannot load the plot font '" + font.file + "' (FreeType)";
    return font;
  }
  // The FreeType library and face are never released: the Cairo face refers
  // to them for the rest of the process.
  font.face = cairo_ft_font_face_create_for_ft_face(ft_face, 0);
  if (cairo_font_face_status(font.face) != CAIRO_STATUS_SUCCESS) {
    font.error = "cannot use the plot font '" + font.file + "' in Cairo";
    font.face = nullptr;
  }
  return font;
}

const LoadedFont& Font() {
  static const LoadedFont font = Load();  // thread-safe once-only initialisation
  if (!font.error.empty()) throw Error(font.error);
  return font;
}

}  // namespace

const std::string& FontFile() { return Font().file; }

void SetFont(cairo_t* cr, double size, bool hinting) {
  cairo_set_font_face(cr, Font().face);
  cairo_set_font_size(cr, size);
  std::unique_ptr<cairo_font_options_t, decltype(&cairo_font_options_destroy)> options(
      cairo_font_options_create(), cairo_font_options_destroy);
  cairo_font_options_set_antialias(options.get(), CAIRO_ANTIALIAS_GRAY);
  cairo_font_options_set_hint_style(options.get(), hinting ? CAIRO_HINT_STYLE_SLIGHT : CAIRO_HINT_STYLE_NONE);
  cairo_font_options_set_hint_metrics(options.get(), CAIRO_HINT_METRICS_OFF);
  cairo_font_options_set_subpixel_order(options.get(), CAIRO_SUBPIXEL_ORDER_DEFAULT);
  cairo_set_font_options(cr, options.get());
}

TextSize MeasureText(const std::string& text, double size) {
  cairo_surface_t* surface = cairo_image_surface_create(CAIRO_FORMAT_RGB24, 1, 1);
  cairo_t* cr = cairo_create(surface);
  SetFont(cr, size, true);
  TextSize out;
  cairo_text_extents_t extents;
  cairo_text_extents(cr, text.c_str(), &extents);
  out.width = extents.x_advance;
  cairo_font_extents_t font;
  cairo_font_extents(cr, &font);
  out.ascent = font.ascent;
  out.descent = font.descent;
  cairo_text_extents(cr, "0", &extents);
  out.digit_height = extents.height;
  cairo_destroy(cr);
  cairo_surface_destroy(surface);
  return out;
}

}  // namespace locforge::plot::internal
