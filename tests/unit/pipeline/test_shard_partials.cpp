// Partial::save / load (docs/scaling.md): InOrderPartial saves its passes' items unfolded and
// loads them back into an empty partial; a short or foreign stream is an InputError; a partial
// whose state is folded cannot be saved.
#include <gtest/gtest.h>

#include <sstream>
#include <string>

#include "pcdp/core/errors.hpp"
#include "pcdp/pipeline/stage.hpp"

using namespace pcdp;

namespace {
struct Sum {
  double s = 0.0;
};
struct Item {
  std::vector<double> v;
};
void save_item(std::ostream& o, const Item& it) {
  partial_io::put_str(o, "test.item");
  partial_io::put_vec(o, it.v);
}
void load_item(std::istream& i, Item& it) {
  partial_io::expect(i, "test.item");
  partial_io::get_vec(i, it.v);
}
using P = InOrderPartial<Sum, Item>;
auto make = [] { return std::make_unique<Sum>(); };
auto fold = [](Sum& s, Item&& it) {
  for (double x : it.v) s.s = s.s * 0.5 + x;  // order matters
};
std::unique_ptr<P> pass(std::size_t k) { return P::of(Item{{double(k), 1.0 / double(k + 1)}}, k == 0, make, fold); }
}  // namespace

TEST(ShardPartials, SavedAndLoadedPartialsFoldToWhatTheOriginalsFold) {
  auto direct = pass(0);
  for (std::size_t k = 1; k < 5; ++k) direct->absorb(std::move(*pass(k)), fold);
  const double want = P::fold_all(direct.get(), make, fold)->s;

  auto running = std::unique_ptr<P>();
  for (std::size_t k = 0; k < 5; ++k) {
    std::stringstream buf;
    pass(k)->save(buf);  // the partial of the first pass too: folding starts at the first merge
    auto loaded = pass(7);  // an empty partial of the type; load replaces its contents
    loaded->load(buf);
    if (!running) running = std::move(loaded);
    else running->absorb(std::move(*loaded), fold);
  }
  EXPECT_EQ(P::fold_all(running.get(), make, fold)->s, want);
}

TEST(ShardPartials, ShortForeignOrFoldedPartialsAreRefused) {
  std::stringstream buf;
  pass(3)->save(buf);
  const std::string all = buf.str();
  for (std::size_t cut : {std::size_t{0}, std::size_t{5}, all.size() / 2, all.size() - 1}) {
    std::stringstream s(all.substr(0, cut));
    auto p = pass(1);
    EXPECT_THROW(p->load(s), InputError) << "cut at " << cut;
  }
  std::stringstream foreign("this is no partial at all, just some text of a length");
  EXPECT_THROW(pass(1)->load(foreign), InputError);
  auto folded = pass(0);
  folded->absorb(std::move(*pass(1)), fold);
  std::stringstream out;
  EXPECT_THROW(folded->save(out), std::logic_error);
}
