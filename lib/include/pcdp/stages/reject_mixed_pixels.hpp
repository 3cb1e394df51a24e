// Stage `reject_mixed_pixels`: returns whose footprint straddled a range edge and whose range lies
// between the two surfaces (Ye & Borenstein 2002, section 4.5: "mixed pixels"; veil points).
//
// For each kept return, along its scan line (bearing) and across lines (nod), with the nearest
// kept neighbours on each side:
//  1. an edge: the nearest neighbours on the two sides (at most max_span steps apart) differ by
//     more than jump_min (or jump_ratio of the range), and the range changes across the return
//     faster per step than within either side: more than edge_factor times (a strong edge), or
//     more than weak_edge_factor times (a weak edge, which counts only where the return does not
//     lie smoothly between its neighbours in the other scan direction: grazing ground changes range
//     in comparable steps and is smooth across; a veil hangs between two slowly changing sides);
//  2. the return fits neither surface alone: its range lies strictly between the two sides, farther
//     than the tolerance (range_tolerance + range_tolerance_ratio * r + 3 sensor.range_sigma) from
//     each side and from each side's linear trend;
//  3. geometry: at the return, the angle between its beam (from its own sensor origin) and the
//     segment to the neighbour on one side or the other is below max_angle (a veil runs along the
//     beam; a mixture close to one surface makes a wide angle with that side only);
//  4. amplitude mixing (models/mixing_model.hpp): with fraction f of the footprint on the near surface, the power-weighted
//     range and amplitude of a mixture are
//         r = (f P1 d1 + (1 - f) P2 d2) / (f P1 + (1 - f) P2),   A = f P1 + (1 - f) P2,
//     so f follows from r, and A must agree with the mixture: not brighter than
//     A (1 + amplitude_ratio) + amplitude_slack (a non-coaxial receiver can only lose light, so a
//     dimmer return is allowed unless the sensor is coaxial). Unknown (NaN) or clipped amplitudes,
//     a side of amplitude 0, and sides whose trends cross (d2 <= d1) skip this test.
// Corners: where a side's first step is itself an edge, more than 3 times its next (a face seen
// edge-on, one return wide, then another surface), the next step stands in for the side's rate;
// such a candidate is a veil only where the return is not flat in the other direction.
// One-sided case (`one_sided`): beside a void (the next position holds no return or only a
// rejected one: the other surface was too weak to return on its own), a return is a mixed pixel
// if it breaks from the trend of the surface on its other side (quadratic where that side is
// three adjacent returns of one smooth surface, allowing a quarter step; else linear, half a step)
// by more than the tolerance (the far surface's depth is unknown, so no edge jump is asked),
// does not continue the surface beyond the void,
// and has the beam geometry of 3. The end of a scan is not a void (ReturnsView::ends_are_voids).
// A return on the plane of a side's 2-D patch (its two nearest returns and the nearest one's
// neighbours in the other scan direction, where the four are one plane) continues that side, in
// test 2 and in the one-sided test; beside a void across lines, a return as bright as its own side
// may lie off that plane by the noise of two poses (`pose_sigma`): a mixture with a void is dimmer.
// A neighbour that keeps the return's range is no witness of a surface where its beam lies inside
// the return's footprint (within half of sensor.beam_divergence, in bearing along a line, in nod
// across lines): two mixtures of one edge keep each other's range. Tests 1-4 read a side past such
// neighbours (in the first round; ReturnsView::along_angle, across_angle, divergence); where no
// strong edge is found, again from the first return a full divergence away (past every footprint
// that overlaps this one; its window starts there, up to 16 positions out), and across lines a
// return whose side read so is a surface and whose other side is a void is judged by the
// one-sided test against that surface (a ramp of mixtures into a void near a nod's turn).
// Spikes (`spikes`, organized passes with across_lines): a run of 1 to spike_width returns, each
// nearer by more than an edge jump than both returns flanking the run along the line, which agree
// with each other (one surface behind it), is a thin object or a mixture of one with the surface
// behind (a 15 cm post at 10 m is one or two returns of a 1 deg scan; with the mixtures on its
// sides, up to three). A thin object (a post) keeps its range from line to line, and the top
// return of a post has the post below it; a mixture's range follows the share of the footprint on
// the object, which changes as the scan moves. So a return of a spike is a mixed pixel where it
// differs by more than the tolerance from each neighbour it has across lines (one is enough: at a
// sweep's end there is one). Where the spike keeps its neighbours' range across lines (a mixture
// at a post's top as the nod turns keeps its share of post and wall), its amplitude decides: it is
// a mixture if it lies behind the brightest return of its object across lines (up to 4 lines each
// way) and in front of the surface behind, each by more than the tolerance, and its amplitude lies
// between the surface's and spike_dim_ratio times the object's, no brighter than test 4's mixture.
// Not used on unorganized clouds, whose range-image bands interleave neighbouring lines.
// Across lines, each nod sweep is a sequence of its own (lines fold back where the nod reverses).
// Amplitudes at or above amplitude_saturation (clipped) skip test 4.
// Only the return itself is labelled `mixed_pixel`, never a window of neighbours.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <vector>

#include "pcdp/pipeline/config.hpp"
#include "pcdp/pipeline/stage.hpp"

namespace pcdp {

struct Pass;

/// The stage's parameters. The pipeline options (reject_mixed_pixels_options, docs/stages.md) set
/// the first group; the second holds the search window, the widest spike and the tests' dimensionless thresholds,
/// fixed for pipelines (no sensor property sets them, and retuning them one by one did not generalize:
/// docs/mixed_pixels.md, Limits) and settable here by library callers only.
struct MixedPixelParams {
  // Pipeline options.
  double jump_min = 0.1;             ///< m
  double jump_ratio = 0.015;
  double range_tolerance = 0.01;     ///< m
  double amplitude_ratio = 0.3;
  double amplitude_slack = 8.0;      ///< amplitude units
  bool across_lines = true;
  bool one_sided = true;
  bool spikes = true;                ///< spikes in front of a surface, off their neighbours across lines
  // Library only.
  /// Returns searched on each side for a side's three nearest usable returns (past dropouts and
  /// rejected returns); a side read past the footprint searches this many past the returns read
  /// past (up to 16). 4 and 16 gave the sweep's recall within 0.002 (docs/mixed_pixels.md).
  int window = 8;
  /// Returns: the widest run along a line taken for a spike (a thin object one or two returns wide
  /// and the mixtures on its sides).
  int spike_width = 3;
  /// Clipped amplitudes say nothing about the mixture. reject_mixed_pixels() takes it from
  /// SensorParams::amplitude_saturation; the functions without a sensor read it here.
  double amplitude_saturation = 255.0;
  double range_tolerance_ratio = 0.002;  ///< the tolerance's part proportional to the range
  double max_angle = 0.9;            ///< rad (52 deg)
  double edge_factor = 1.5;          ///< strong edge: per-step change across the return vs within each side
  double weak_edge_factor = 0.8;     ///< weak edge: flagged only if not smooth in the other direction (<= edge_factor)
  double spike_dim_ratio = 0.9;      ///< a spike flat across lines is a mixture below this x its object's brightest return (0: off)
  int max_span = 6;                  ///< steps between the two sides' nearest neighbours
};

/// The options of `reject_mixed_pixels`, bound to MixedPixelParams.
const Options<MixedPixelParams>& reject_mixed_pixels_options();
const OptionSchema& reject_mixed_pixels_schema();

/// Plain arrays of registered returns (map frame) for the core algorithm.
struct ReturnsView {
  std::size_t n = 0;
  const double *x = nullptr, *y = nullptr, *z = nullptr;     ///< points
  const double *ox = nullptr, *oy = nullptr, *oz = nullptr;  ///< sensor origin of each return
  const float* range = nullptr;                              ///< range of each return
  const float* amplitude = nullptr;                          ///< may be null or NaN: unknown
  const char* usable = nullptr;                              ///< candidate and neighbour (kept)
  /// Whether the ends of a sequence are voids: in a cloud's range image the rows hold only the
  /// returns there are, so a row ends where the returns stop; an organized scan's lines end at
  /// the edge of its field of view, which says nothing about a missing surface.
  bool ends_are_voids = false;
  /// If set, only these returns are tested (their neighbours still count): the later rounds for
  /// runs of mixtures test only the returns next to one found in the round before. A view with a
  /// focus is a later round: its two-sided tests do not read past neighbours that share the
  /// footprint (below).
  const char* focus = nullptr;
  /// An organized pass: returns per line (0: not organized). With it, a side's two nearest
  /// returns and the neighbours of the nearest in the other scan direction than the sequences
  /// tested (the same beam on the lines before and after, `width` returns away, for sequences
  /// along a line; the beams beside it on its line for sequences across lines) make a 2-D patch
  /// whose plane a return may continue.
  std::size_t width = 0;
  /// The sequences run across lines: a return's patch is on another line, and its neighbours'
  /// beams are compared by `across_angle`, not `along_angle`.
  bool across = false;
  /// 1-sigma noise of the poses a line is registered with (position m, rpy rad; pose_sigma): two
  /// lines' returns of one surface differ by it as well as by range noise.
  double pose_position_sigma = 0.0, pose_rpy_sigma = 0.0;
  /// Each return's beam angle in each scan direction (bearing along a line, nod across lines; null:
  /// unknown) and the full beam divergence (rad, 0: unknown). A neighbour whose beam lies within
  /// half the divergence of a return's (inside its footprint) and keeps its range witnesses no
  /// surface in tests 1-4; equal angles say nothing.
  const float *along_angle = nullptr, *across_angle = nullptr;
  double divergence = 0.0;
};

/// What `mark_mixed_pixels` found at a return, in one scan direction.
enum MixedEdge : char {
  kNoEdge = 0,
  kWeakEdge = 1,    ///< flagged only where the return is rough in the other direction
  kCornerEdge = 2,  ///< one side is a surface one return wide (its next step is an edge): flagged
                    ///< unless the return is flat in the other direction (a face seen edge-on)
  kStrongEdge = 3,  ///< flagged
  kBesideVoid = 4,  ///< one-sided (test 5): beside a void, off the trend of its one surface: flagged
};

/// Marks the mixed-pixel candidates among the returns of one sequence of indices in scan order
/// (a scan line, or one beam across lines), as MixedEdge values.
void mark_mixed_pixels(const ReturnsView& v, const std::vector<std::size_t>& seq, const MixedPixelParams& p,
                       double range_sigma, bool coaxial, std::vector<char>& mixed);

/// The stage's function over a registered pass: labels mixed pixels, returns how many.
/// `pose_sigma` is the noise of the poses between lines (the `pose_sigma:` block); the default is
/// none: returns of one surface on different lines differ by range noise only. (A
/// default-constructed PoseSigma{} is the pipeline's default noise, 5 mm and 0.35 mrad, not none.)
std::size_t reject_mixed_pixels(Pass& pass, const MixedPixelParams& p, const SensorParams& sensor,
                                const PoseSigma& pose_sigma = PoseSigma{0.0, 0.0});

/// How an unorganized cloud's points are put back into scan order.
enum class CloudAngles {
  kNodding,    ///< a nodding 2-D scanner: rows of equal nod atan2(z, x), sorted by bearing atan2(y, hypot(x, z))
  kSpherical,  ///< rows of equal elevation, sorted by azimuth (e.g. a panning scanner, a range camera)
};

/// An unorganized Cartesian cloud seen from one viewpoint (e.g. a cloud someone already has):
/// points are ordered into a range image in the sensor frame (`orientation`: sensor frame in the
/// cloud frame): rows `resolution` rad wide sorted along the row, columns sorted across, and the
/// same tests run along both. A nodding scanner's lines are rows of equal nod (kNodding); its
/// elevation varies along a line, so elevation bands (kSpherical) cut across its lines.
/// `resolution` is about the scan's angular step. `amplitude` may be empty. Returns a mask of
/// mixed pixels. The spike test is not used here (see above).
std::vector<char> mixed_pixels_in_cloud(const std::vector<Eigen::Vector3d>& points, const Eigen::Vector3d& viewpoint,
                                        const std::vector<float>& amplitude, double resolution,
                                        const MixedPixelParams& p, double range_sigma,
                                        CloudAngles angles = CloudAngles::kSpherical,
                                        const Eigen::Quaterniond& orientation = Eigen::Quaterniond::Identity());

StageInfo reject_mixed_pixels_stage_info();

}  // namespace pcdp
