// elevation.tif's writer: DEFLATE by libdeflate in the WorkShare's tasks, the blocks handed to
// libtiff compressed (TIFFWriteRawStrip/Tile, what write_elevation_geotiff does), against
// libtiff's own DEFLATE codec compressing each block as it is written. The same raster both ways:
// 20 float32 bands (the merge state's) of 1,024 x 1,024 cells, smooth heights with noise and
// holes, strips of 64 KiB, level 1.
//   ./build/bench/pcdp_tiff_bench
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>
#include <vector>

#include "io/tiff_writer.hpp"
#include "pcdp/pipeline/work_share.hpp"

namespace {
using pcdp::WorkShare;
using pcdp::io::detail::Block;
using pcdp::io::detail::FloatTiff;

FloatTiff raster(bool libtiff_codec) {
  FloatTiff t;
  t.width = t.height = 1024;
  t.bands = 20;
  t.rows_per_strip = 16;  // 64 KiB of a band
  t.groups = {4, 4, 4, 4, 4};
  t.pixel_scale[0] = t.pixel_scale[1] = 0.1;
  t.gdal_nodata = "nan";
  t.libtiff_codec = libtiff_codec;
  return t;
}

/// Band b's values: smooth heights on the cell scale plus a little noise (the low mantissa bits of
/// a fused mean are noise too), every seventh cell unobserved. Computed once, outside the timing.
const std::vector<float>& plane(int b) {
  static const std::vector<std::vector<float>> planes = [] {
    std::vector<std::vector<float>> p(20, std::vector<float>(1024 * 1024));
    for (int k = 0; k < 20; ++k)
      for (int y = 0; y < 1024; ++y)
        for (int x = 0; x < 1024; ++x) {
          const unsigned h = static_cast<unsigned>(x) * 73856093u ^ static_cast<unsigned>(y) * 19349663u ^ static_cast<unsigned>(k) * 83492791u;
          float v = static_cast<float>(std::sin(x * 0.01) * std::cos(y * 0.013) + (h % 1000) * 1e-5);
          if (h % 7 == 0) v = std::numeric_limits<float>::quiet_NaN();
          p[static_cast<std::size_t>(k)][static_cast<std::size_t>(y) * 1024 + static_cast<std::size_t>(x)] = v;
        }
    return p;
  }();
  return planes[static_cast<std::size_t>(b)];
}

bool fill(int first, const Block& b, std::vector<std::vector<float>>& planes) {
  for (std::size_t j = 0; j < planes.size(); ++j) {
    const float* src = plane(first + static_cast<int>(j)).data() + static_cast<std::size_t>(b.y0) * 1024;
    std::copy(src, src + planes[j].size(), planes[j].begin());
  }
  return true;
}

void write(benchmark::State& state, bool libtiff_codec, unsigned threads) {
  const std::string path = "/tmp/pcdp_tiff_bench_" + std::to_string(libtiff_codec) + std::to_string(threads) + ".tif";
  const FloatTiff t = raster(libtiff_codec);
  const auto share = WorkShare::threads(threads);
  plane(0);
  for (auto _ : state) pcdp::io::detail::write_float_tiff_blocks(path, t, 1, fill, *share);
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (f) {
    std::fseek(f, 0, SEEK_END);
    state.counters["MB"] = static_cast<double>(std::ftell(f)) / 1e6;
    std::fclose(f);
  }
  std::remove(path.c_str());
}
void BM_RawStrips_Libdeflate_1Thread(benchmark::State& s) { write(s, false, 1); }
void BM_RawStrips_Libdeflate_2Threads(benchmark::State& s) { write(s, false, 2); }
void BM_LibtiffCodec(benchmark::State& s) { write(s, true, 1); }
// Wall time, and the CPU time of the whole process (every thread's).
BENCHMARK(BM_RawStrips_Libdeflate_1Thread)->Unit(benchmark::kMillisecond)->UseRealTime()->MeasureProcessCPUTime();
BENCHMARK(BM_RawStrips_Libdeflate_2Threads)->Unit(benchmark::kMillisecond)->UseRealTime()->MeasureProcessCPUTime();
BENCHMARK(BM_LibtiffCodec)->Unit(benchmark::kMillisecond)->UseRealTime()->MeasureProcessCPUTime();
}  // namespace
