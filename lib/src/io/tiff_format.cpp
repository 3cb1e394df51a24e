#include "tiff_format.hpp"

#include <geotiff/xtiffio.h>

#include <cstdarg>
#include <cstdio>
#include <mutex>

namespace pcdp::io::detail {

namespace {
TIFFExtendProc g_parent = nullptr;

// GDAL's two ASCII tags, as GDAL registers them: without this libtiff reads them as anonymous
// fields and writes none.
void extend(TIFF* tif) {
  static const TIFFFieldInfo fields[] = {
      {kTagGdalMetadata, -1, -1, TIFF_ASCII, FIELD_CUSTOM, 1, 0, const_cast<char*>("GDALMetadata")},
      {kTagGdalNodata, -1, -1, TIFF_ASCII, FIELD_CUSTOM, 1, 0, const_cast<char*>("GDALNoDataValue")},
  };
  TIFFMergeFieldInfo(tif, fields, sizeof fields / sizeof fields[0]);
  if (g_parent) g_parent(tif);
}

void register_tags() {
  static std::once_flag once;
  std::call_once(once, [] {
    XTIFFInitialize();  // libgeotiff's extender: ModelPixelScale, ModelTiepoint, the GeoKey directory
    g_parent = TIFFSetTagExtender(extend);
  });
}

int on_error(TIFF*, void* user, const char* module, const char* fmt, va_list ap) {
  auto* m = static_cast<TiffMessages*>(user);
  if (m->error.empty()) {
    char buf[512];
    std::vsnprintf(buf, sizeof buf, fmt, ap);
    m->error = buf;
    (void)module;
  }
  return 1;  // handled: nothing on stderr
}
int on_warning(TIFF*, void* user, const char*, const char* fmt, va_list ap) {
  auto* m = static_cast<TiffMessages*>(user);
  if (m->warning.empty()) {
    char buf[512];
    std::vsnprintf(buf, sizeof buf, fmt, ap);
    m->warning = buf;
  }
  return 1;
}
}  // namespace

void TiffCloser::operator()(TIFF* t) const {
  if (t) TIFFClose(t);
}

TiffPtr open_tiff(const std::string& path, const char* mode, TiffMessages& msgs, std::uint64_t max_alloc) {
  register_tags();
  TIFFOpenOptions* opts = TIFFOpenOptionsAlloc();
  if (!opts) {
    msgs.error = "out of memory";
    return nullptr;
  }
  TIFFOpenOptionsSetErrorHandlerExtR(opts, on_error, &msgs);
  TIFFOpenOptionsSetWarningHandlerExtR(opts, on_warning, &msgs);
  if (max_alloc) TIFFOpenOptionsSetMaxSingleMemAlloc(opts, static_cast<tmsize_t>(max_alloc));
  TIFF* t = TIFFOpenExt(path.c_str(), mode, opts);
  TIFFOpenOptionsFree(opts);
  if (!t && msgs.error.empty()) msgs.error = "libtiff cannot open it";
  return TiffPtr(t);
}

}  // namespace pcdp::io::detail
