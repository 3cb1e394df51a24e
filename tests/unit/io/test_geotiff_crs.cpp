// elevation.tif's CRS (the pipeline key `crs`, GeoKeys through libgeotiff) and its bands: the
// user's six, read back through GDAL with statistics and no error; the merge state beside it.
#include <cpl_error.h>
#include <gdal_priv.h>
#include <gtest/gtest.h>
#include <ogr_spatialref.h>

#include <cstdlib>
#include <functional>
#include <stdexcept>
#include <string>

#include "pcdp/fusion/elevation.hpp"
#include "pcdp/core/errors.hpp"
#include "pcdp/io/geotiff.hpp"
#include "test_support.hpp"

using namespace pcdp;

namespace {
std::string rule_of(const std::string& crs) {
  try {
    io::normalize_crs(crs);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

/// GDAL errors raised while `f` runs, counted (not printed).
int gdal_errors(const std::function<void()>& f) {
  static int count = 0;
  count = 0;
  CPLPushErrorHandler([](CPLErr level, CPLErrorNum, const char*) {
    if (level >= CE_Failure) ++count;
  });
  f();
  CPLPopErrorHandler();
  return count;
}

ElevationGrid small_grid() {
  ElevationGrid g(0.25, 0.05);
  for (int i = 0; i < 40; ++i) g.add(500000.1 + 0.25 * (i % 7), 5000000.3 + 0.25 * (i / 7), 0.5 + 0.01 * i, 1e-4, 0);
  for (int i = 0; i < 40; ++i) g.add(500000.1 + 0.25 * (i % 7), 5000000.3 + 0.25 * (i / 7), 0.52 + 0.01 * i, 1e-4, 1);
  return g;
}
}  // namespace

TEST(GeoTiffCrs, EpsgCodesAndWktAreCheckedAgainstProj) {
  EXPECT_EQ(io::normalize_crs("EPSG:32632"), "EPSG:32632");
  EXPECT_EQ(io::normalize_crs("epsg:25832"), "EPSG:25832");
  EXPECT_EQ(io::normalize_crs(""), "");
  // The WKT of an EPSG CRS is that code.
  OGRSpatialReference srs;
  ASSERT_EQ(srs.importFromEPSG(32633), OGRERR_NONE);
  char* wkt = nullptr;
  srs.exportToWkt(&wkt);
  EXPECT_EQ(io::normalize_crs(wkt), "EPSG:32633");
  CPLFree(wkt);
  EXPECT_NE(rule_of("EPSG:4326").find("a geographic CRS (degrees)"), std::string::npos) << rule_of("EPSG:4326");
  EXPECT_NE(rule_of("EPSG:2263").find("not metres"), std::string::npos) << rule_of("EPSG:2263");
  // Axes pointing west and south (Hartebeesthoek94 / Lo15) or not east and north at all (a polar
  // stereographic CRS) would lay the grid's east-north cells the wrong way round.
  EXPECT_NE(rule_of("EPSG:2046").find("axes point west and south"), std::string::npos) << rule_of("EPSG:2046");
  EXPECT_NE(rule_of("EPSG:3031").find("must point east and north"), std::string::npos) << rule_of("EPSG:3031");
  EXPECT_EQ(io::normalize_crs("EPSG:25832"), "EPSG:25832");  // ETRS89 / UTM 32N: east, north
  EXPECT_NE(rule_of("EPSG:1234").find("not a CRS in PROJ's EPSG database"), std::string::npos) << rule_of("EPSG:1234");
  EXPECT_NE(rule_of("EPSG:32632x").find("a whole number in 1 .. 32766"), std::string::npos);
  EXPECT_NE(rule_of("EPSG:40000").find("a whole number in 1 .. 32766"), std::string::npos);
  EXPECT_NE(rule_of("UTM 32").find("neither EPSG:<code> nor WKT that PROJ reads"), std::string::npos);
  const std::string local =
      "PROJCS[\"local TM\",GEOGCS[\"WGS 84\",DATUM[\"WGS_1984\",SPHEROID[\"WGS 84\",6378137,298.257223563]],"
      "PRIMEM[\"Greenwich\",0],UNIT[\"degree\",0.0174532925199433]],PROJECTION[\"Transverse_Mercator\"],"
      "PARAMETER[\"latitude_of_origin\",0],PARAMETER[\"central_meridian\",9.3],PARAMETER[\"scale_factor\",1],"
      "PARAMETER[\"false_easting\",1000],PARAMETER[\"false_northing\",0],UNIT[\"metre\",1]]";
  EXPECT_NE(rule_of(local).find("'local TM' has no EPSG code"), std::string::npos) << rule_of(local);
}

TEST(GeoTiffCrs, GdalReadsTheEpsgCodeAndStatisticsOfTheSixBandsWithoutAnError) {
  const std::string dir = test::fresh_dir();
  const ElevationGrid g = small_grid();
  io::write_elevation_geotiff(g, dir + "/e.tif", 1, run_in_order, "EPSG:32632");
  io::write_elevation_geotiff(g, dir + "/plain.tif");
  GDALAllRegister();
  for (const std::string& name : {std::string("e.tif"), std::string("e.state.tif")}) {
    GDALDataset* ds = static_cast<GDALDataset*>(GDALOpen((dir + "/" + name).c_str(), GA_ReadOnly));
    ASSERT_NE(ds, nullptr) << name;
    const OGRSpatialReference* srs = ds->GetSpatialRef();
    ASSERT_NE(srs, nullptr) << name;
    ASSERT_NE(srs->GetAuthorityCode(nullptr), nullptr) << name;
    EXPECT_STREQ(srs->GetAuthorityCode(nullptr), "32632") << name;
    EXPECT_TRUE(srs->IsProjected()) << name;
    if (name == "e.tif") {
      ASSERT_EQ(ds->GetRasterCount(), 6);
      const char* names[] = {"elevation", "variance", "count", "min", "max", "passes"};
      int errors = gdal_errors([&] {
        for (int b = 1; b <= 6; ++b) {
          GDALRasterBand* band = ds->GetRasterBand(b);
          EXPECT_STREQ(band->GetDescription(), names[b - 1]);
          double mn = 0, mx = 0, mean = 0, sd = 0;
          EXPECT_EQ(band->ComputeStatistics(FALSE, &mn, &mx, &mean, &sd, nullptr, nullptr), CE_None) << names[b - 1];
          EXPECT_LE(mn, mx);
        }
      });
      EXPECT_EQ(errors, 0);
      double mn = 0, mx = 0, mean = 0, sd = 0;
      ds->GetRasterBand(3)->ComputeStatistics(FALSE, &mn, &mx, &mean, &sd, nullptr, nullptr);
      EXPECT_EQ(mx, 2.0);  // every cell has two points
    } else {
      EXPECT_EQ(ds->GetRasterCount(), 20);
      EXPECT_STREQ(ds->GetRasterBand(1)->GetDescription(), "count");
      EXPECT_STREQ(ds->GetRasterBand(5)->GetDescription(), "height_band_0_index");
    }
    GDALClose(ds);
  }
  EXPECT_EQ(io::elevation_geotiff_crs(dir + "/e.tif"), "EPSG:32632");
  EXPECT_EQ(io::elevation_geotiff_crs(dir + "/plain.tif"), "");
  // gdalinfo -stats, as a user would run it: no ERROR line.
  const std::string txt = dir + "/stats.txt";
  ASSERT_EQ(std::system(("gdalinfo -stats " + dir + "/e.tif > " + txt + " 2>&1").c_str()), 0);
  const std::string info = test::read_text(txt);
  EXPECT_EQ(info.find("ERROR"), std::string::npos) << info;
  EXPECT_NE(info.find("ID[\"EPSG\",32632]]"), std::string::npos) << info;
  // The grid reads back from the state alone, the same grid.
  const ElevationGrid back = io::read_elevation_geotiff(dir + "/e.tif");
  EXPECT_EQ(back.size(), g.size());
}
