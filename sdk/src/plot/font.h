// The figures' typeface, loaded once per process, and text measurement.
#ifndef LOCFORGE_SDK_SRC_PLOT_FONT_H_
#define LOCFORGE_SDK_SRC_PLOT_FONT_H_

#include <cairo.h>

#include <string>

namespace locforge::plot::internal {

// The font file every figure uses: DejaVu Sans as fontconfig finds it, or
// fontconfig's best sans-serif. Throws locforge::Error when there is none.
const std::string& FontFile();

// Selects the figure font at `size` pixels on `cr`, with fixed rendering
// options (greyscale antialiasing, unhinted metrics), so the text is laid out
// identically in the PNG, the SVG and the measurements, whatever the
// machine's fontconfig settings say. `hinting` (slight) sharpens small text
// on pixels; vector output keeps the true outlines.
void SetFont(cairo_t* cr, double size, bool hinting);

struct TextSize {
  double width = 0;    // advance of the whole string
  double ascent = 0;   // of the font, above the baseline
  double descent = 0;  // of the font, below the baseline
  double digit_height = 0;  // height of "0": centres numbers on ticks
};
TextSize MeasureText(const std::string& text, double size);

}  // namespace locforge::plot::internal

#endif  // LOCFORGE_SDK_SRC_PLOT_FONT_H_
