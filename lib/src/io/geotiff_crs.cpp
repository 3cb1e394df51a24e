#include "geotiff_crs.hpp"

#include <geotiff/geovalues.h>
#include <proj.h>

#include <cmath>
#include <memory>
#include <stdexcept>

#include "pcdp/io/geotiff.hpp"

namespace pcdp::io {

namespace {
struct ContextFree {
  void operator()(PJ_CONTEXT* c) const { proj_context_destroy(c); }
};
struct PjFree {
  void operator()(PJ* p) const { proj_destroy(p); }
};
using Pj = std::unique_ptr<PJ, PjFree>;

/// "N" of "EPSG:N" (1 .. 32766, GeoKeys' SHORT codes; KvUserDefined is 32767); 0 when `text`
/// does not start with "EPSG:" (any case).
int epsg_code(const std::string& text) {
  if (text.size() < 5) return 0;
  for (std::size_t i = 0; i < 4; ++i)
    if (std::toupper(static_cast<unsigned char>(text[i])) != "EPSG"[i]) return 0;
  if (text[4] != ':') return 0;
  const std::string digits = text.substr(5);
  if (digits.empty() || digits.size() > 5 || digits.find_first_not_of("0123456789") != std::string::npos)
    throw std::invalid_argument("'" + text + "': an EPSG code is EPSG: and a whole number in 1 .. 32766");
  const int n = std::stoi(digits);
  if (n < 1 || n > 32766) throw std::invalid_argument("'" + text + "': an EPSG code is EPSG: and a whole number in 1 .. 32766");
  return n;
}

/// InputError-free checks of a CRS PROJ made: projected, map x and y in metres.
void check_projected_metres(PJ_CONTEXT* ctx, PJ* crs, const std::string& what) {
  const PJ_TYPE type = proj_get_type(crs);
  if (type != PJ_TYPE_PROJECTED_CRS) {
    const bool geographic = type == PJ_TYPE_GEOGRAPHIC_2D_CRS || type == PJ_TYPE_GEOGRAPHIC_3D_CRS;
    throw std::invalid_argument(what + " is " + (geographic ? "a geographic CRS (degrees)" : "not a projected CRS") +
                                ": elevation.tif's cells are metres east and north on the map, so the CRS must be a "
                                "projected one in metres (e.g. UTM, EPSG:326NN)");
  }
  const Pj cs(proj_crs_get_coordinate_system(ctx, crs));
  if (!cs || proj_cs_get_axis_count(ctx, cs.get()) < 2)
    throw std::invalid_argument(what + ": PROJ finds no coordinate system in it");
  std::vector<std::string> dirs;  // the two axes' directions: east and north, in either order
  for (int i = 0; i < 2; ++i) {
    double factor = 0;
    const char* unit = nullptr;
    const char* direction = nullptr;
    if (!proj_cs_get_axis_info(ctx, cs.get(), i, nullptr, nullptr, &direction, &factor, &unit, nullptr, nullptr) ||
        std::fabs(factor - 1.0) > 1e-12)
      throw std::invalid_argument(what + ": its axes are in " + (unit ? unit : "an unknown unit") +
                                  ", not metres: elevation.tif's cells are metres on the map");
    std::string d = direction ? direction : "unknown";
    for (auto& c : d) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    dirs.push_back(d);
  }
  // A CRS whose axes point west or south (some Transverse Mercator systems of southern Africa) or
  // along meridians (polar stereographic) would put the grid's east-north cells the wrong way.
  if (!((dirs[0] == "east" && dirs[1] == "north") || (dirs[0] == "north" && dirs[1] == "east")))
    throw std::invalid_argument(what + ": its axes point " + dirs[0] + " and " + dirs[1] +
                                "; elevation.tif's cells run east and north, so the CRS's axes must point east and north");
}
}  // namespace

std::string normalize_crs(const std::string& text) {
  if (text.empty()) return text;
  const std::unique_ptr<PJ_CONTEXT, ContextFree> ctx(proj_context_create());
  if (!ctx) throw std::runtime_error("cannot set up PROJ");
  proj_log_level(ctx.get(), PJ_LOG_NONE);  // PROJ's messages come back as the rule, not on stderr
  if (const int code = epsg_code(text)) {
    const std::string name = "EPSG:" + std::to_string(code);
    const Pj crs(proj_create_from_database(ctx.get(), "EPSG", std::to_string(code).c_str(), PJ_CATEGORY_CRS, 0, nullptr));
    if (!crs) throw std::invalid_argument("'" + text + "': " + name + " is not a CRS in PROJ's EPSG database");
    check_projected_metres(ctx.get(), crs.get(), name + " (" + proj_get_name(crs.get()) + ")");
    return name;
  }
  // Otherwise WKT (1 or 2), parsed strictly.
  PROJ_STRING_LIST warnings = nullptr, errors = nullptr;
  const char* const options[] = {"STRICT=YES", nullptr};
  const Pj crs(proj_create_from_wkt(ctx.get(), text.c_str(), options, &warnings, &errors));
  std::string why = errors && errors[0] ? errors[0] : "";
  proj_string_list_destroy(warnings);
  proj_string_list_destroy(errors);
  if (!crs)
    throw std::invalid_argument("'" + (text.size() > 60 ? text.substr(0, 60) + "...'" : text + "'") +
                                " is neither EPSG:<code> nor WKT that PROJ reads" + (why.empty() ? "" : " (" + why + ")"));
  check_projected_metres(ctx.get(), crs.get(), "the WKT CRS '" + std::string(proj_get_name(crs.get())) + "'");
  // A WKT of an EPSG CRS is written as its code (what GDAL and QGIS recognise best).
  int* confidence = nullptr;
  PJ_OBJ_LIST* found = proj_identify(ctx.get(), crs.get(), "EPSG", nullptr, &confidence);
  std::string code;
  if (found && proj_list_get_count(found) > 0 && confidence && confidence[0] == 100) {
    const Pj best(proj_list_get(ctx.get(), found, 0));
    if (best && proj_get_id_code(best.get(), 0)) code = proj_get_id_code(best.get(), 0);
  }
  proj_int_list_destroy(confidence);
  proj_list_destroy(found);
  if (!code.empty() && code.size() <= 5 && code.find_first_not_of("0123456789") == std::string::npos &&
      std::stoi(code) >= 1 && std::stoi(code) <= 32766)
    return "EPSG:" + code;
  // libgeotiff writes GeoKeys from codes, not from WKT (that translation lives in GDAL), and a CRS
  // given only as text in GTCitationGeoKey reads back in GDAL as an unknown or engineering CRS:
  // a file that would mislead its reader is refused here.
  throw std::invalid_argument("the WKT CRS '" + std::string(proj_get_name(crs.get())) +
                              "' has no EPSG code (PROJ identifies none with full confidence): elevation.tif states its "
                              "CRS as an EPSG code in its GeoKeys");
}

namespace detail {

GeoKeys crs_geokeys(const std::string& crs) {
  GeoKeys k;
  if (crs.empty()) return k;
  k.model = ModelTypeProjected;
  if (const int code = epsg_code(crs)) {
    k.epsg = code;
  } else {
    throw std::invalid_argument("crs '" + crs + "' is not EPSG:<code> (normalize_crs() makes it one)");
  }
  return k;
}

std::string crs_of(const GeoKeys& k) {
  if (k.model == 0) return "";
  if (k.epsg > 0 && k.epsg != KvUserDefined) return "EPSG:" + std::to_string(k.epsg);
  if (!k.citation.empty()) return k.citation;
  return "a user-defined CRS without a citation";
}

}  // namespace detail
}  // namespace pcdp::io
