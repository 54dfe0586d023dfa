#include "locforge/image_check.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <csetjmp>
#include <cstdint>
#include <cstdio>  // jpeglib.h needs size_t and FILE declared first
#include <exception>
#include <fstream>
#include <string_view>

#include <jpeglib.h>
// After jpeglib.h, which it extends.
#include <jerror.h>

namespace locforge {

namespace {

struct JpegErrors {
  jpeg_error_mgr mgr;
  std::jmp_buf jump;
  int code = 0;
  char message[JMSG_LENGTH_MAX] = {};
};

[[noreturn]] void JpegAbort(j_common_ptr cinfo) {
  auto* errors = reinterpret_cast<JpegErrors*>(cinfo->err);
  errors->code = cinfo->err->msg_code;
  cinfo->err->format_message(cinfo, errors->message);
  std::longjmp(errors->jump, 1);
}

// Warnings (level -1) are libjpeg's word for lost or skipped data: each one
// ends the decode as an error, except those about metadata only.
void JpegMessage(j_common_ptr cinfo, int level) {
  if (level >= 0) return;  // trace messages
  const int code = cinfo->err->msg_code;
  if (code == JWRN_JFIF_MAJOR || code == JWRN_ADOBE_XFORM || code == JWRN_BOGUS_ICC) return;
  JpegAbort(cinfo);
}

// Entropy-decodes every scan (where truncation and corrupt data show) at
// 1/8 scale in grey, which skips most of the inverse DCT and colour work.
std::string JpegDamage(const std::string& data) {
  JpegErrors errors;
  jpeg_decompress_struct cinfo;
  cinfo.err = jpeg_std_error(&errors.mgr);
  errors.mgr.error_exit = JpegAbort;
  errors.mgr.emit_message = JpegMessage;
  jpeg_create_decompress(&cinfo);
  if (setjmp(errors.jump)) {
    jpeg_destroy_decompress(&cinfo);
    const char* kind = errors.code == JWRN_JPEG_EOF ? "truncated" : "corrupt";
    return std::string(kind) + " JPEG (libjpeg: " + errors.message + ")";
  }
  jpeg_mem_src(&cinfo, reinterpret_cast<const unsigned char*>(data.data()),
               static_cast<unsigned long>(data.size()));
  jpeg_read_header(&cinfo, TRUE);
  cinfo.scale_num = 1;
  cinfo.scale_denom = 8;
  cinfo.dct_method = JDCT_IFAST;
  cinfo.do_fancy_upsampling = FALSE;
  if (cinfo.jpeg_color_space == JCS_YCbCr || cinfo.jpeg_color_space == JCS_GRAYSCALE)
    cinfo.out_color_space = JCS_GRAYSCALE;
  jpeg_start_decompress(&cinfo);
  // Allocated in libjpeg's pool: freed by jpeg_destroy_decompress, even after a longjmp.
  JSAMPARRAY row = (*cinfo.mem->alloc_sarray)(reinterpret_cast<j_common_ptr>(&cinfo), JPOOL_IMAGE,
                                              cinfo.output_width * cinfo.output_components, 1);
  while (cinfo.output_scanline < cinfo.output_height) jpeg_read_scanlines(&cinfo, row, 1);
  jpeg_finish_decompress(&cinfo);  // reads on to the EOI marker
  jpeg_destroy_decompress(&cinfo);
  return "";
}

uint32_t Crc32(std::string_view bytes) {
  static const auto table = [] {
    std::array<uint32_t, 256> t{};
    for (uint32_t n = 0; n < 256; ++n) {
      uint32_t c = n;
      for (int k = 0; k < 8; ++k) c = (c & 1) ? 0xedb88320u ^ (c >> 1) : c >> 1;
      t[n] = c;
    }
    return t;
  }();
  uint32_t c = 0xffffffffu;
  for (unsigned char b : bytes) c = table[(c ^ b) & 0xff] ^ (c >> 8);
  return c ^ 0xffffffffu;
}

uint32_t BigEndian32(std::string_view bytes, size_t at) {
  uint32_t v = 0;
  for (size_t i = 0; i < 4; ++i) v = v << 8 | static_cast<unsigned char>(bytes[at + i]);
  return v;
}

// Chunk by chunk from the signature to IEND: every length within the file,
// every CRC right (a corrupt IDAT fails its CRC), IHDR first.
std::string PngDamage(std::string_view data) {
  size_t at = 8;
  for (int chunk = 0;; ++chunk) {
    if (data.size() - at < 12)
      return "truncated PNG (ends at byte " + std::to_string(data.size()) + " without an IEND chunk)";
    const uint32_t length = BigEndian32(data, at);
    const std::string type(data.substr(at + 4, 4));
    const std::string where = "chunk '" + type + "' at byte " + std::to_string(at);
    if (length > data.size() - at - 12) return "truncated PNG (" + where + " runs past the end)";
    if (chunk == 0 && type != "IHDR") return "corrupt PNG (first chunk is '" + type + "', not IHDR)";
    if (Crc32(data.substr(at + 4, 4 + length)) != BigEndian32(data, at + 8 + length))
      return "corrupt PNG (CRC mismatch in " + where + ")";
    if (type == "IEND") return "";
    at += 12 + length;
  }
}

std::string Lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

}  // namespace

std::string ImageFileDamage(const std::filesystem::path& file) {
  try {
    std::ifstream in(file, std::ios::binary | std::ios::ate);
    if (!in) return "cannot open the file";
    std::string data(static_cast<size_t>(std::max<std::streamoff>(0, in.tellg())), '\0');
    in.seekg(0);
    if (!in.read(data.data(), static_cast<std::streamsize>(data.size()))) return "cannot read the file";
    if (data.empty()) return "empty file";
    const std::string ext = Lower(file.extension().string());
    if (data.size() >= 2 && data.compare(0, 2, "\xff\xd8") == 0) return JpegDamage(data);
    if (data.size() >= 8 && data.compare(0, 8, "\x89PNG\r\n\x1a\n", 8) == 0) return PngDamage(data);
    if (ext == ".jpg" || ext == ".jpeg") return "not a JPEG (no FF D8 start marker)";
    if (ext == ".png") return "not a PNG (no PNG signature)";
    return "";
  } catch (const std::exception& e) {
    return std::string("cannot check the file: ") + e.what();
  }
}

}  // namespace locforge
