#include "passive_drift.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Cholesky>

namespace maglead::twin {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

/// Solves the normal equations A θ = b by Cholesky (A symmetric); inv receives A⁻¹. False when A
/// is not positive definite (a regressor the window does not excite: a pivot of L at or below
/// 1e-6). Fixed-size Eigen: no allocation.
template <std::size_t N>
bool solve_normal(const std::array<std::array<double, N>, N>& a, const std::array<double, N>& b,
                  std::array<double, N>& theta, std::array<std::array<double, N>, N>& inv) {
  constexpr int n = static_cast<int>(N);
  Eigen::Matrix<double, n, n> m;
  Eigen::Matrix<double, n, 1> rhs;
  for (int i = 0; i < n; ++i) {
    rhs(i) = b[static_cast<std::size_t>(i)];
    for (int j = 0; j < n; ++j)
      m(i, j) = a[static_cast<std::size_t>(i)][static_cast<std::size_t>(j)];
  }
  const Eigen::LLT<Eigen::Matrix<double, n, n>> llt(m);
  if (llt.info() != Eigen::Success || !(llt.matrixL().toDenseMatrix().diagonal().minCoeff() > 1e-6))
    return false;
  const Eigen::Matrix<double, n, 1> x = llt.solve(rhs);
  const Eigen::Matrix<double, n, n> mi = llt.solve(Eigen::Matrix<double, n, n>::Identity());
  for (int i = 0; i < n; ++i) {
    theta[static_cast<std::size_t>(i)] = x(i);
    for (int j = 0; j < n; ++j)
      inv[static_cast<std::size_t>(i)][static_cast<std::size_t>(j)] = mi(i, j);
  }
  return true;
}

}  // namespace

PassiveLoadDrift::PassiveLoadDrift(const PassiveDriftSettings& s) : s_(s) {
  // The map covers the stroke: cells no finer than the stroke over the cells there are.
  s_.bin_m = std::max(s_.bin_m, (s_.stroke_max_m - s_.stroke_min_m) / kBins);
  clear();
}

void PassiveLoadDrift::clear() noexcept {
  n_blocks_ = slide_first_ = 0;
  map_.fill(Cell{});
  win_s_ = slide_s_ = 0;
  b_n_ = 0;
  ref_s_ = ref_t_sum_ = ref_t_ = 0;
  ref_n_ = 0;
  ref_frozen_ = seen_ = updated_ = in_stretch_ = false;
  stretch_ = map_stretch_ = 0;
  shift_m_ = 0;
  disp_gain_ = disp_step_ = Dispersion{};
  gain_ = step_ = Mean{};
  fc_s_ = used_s_ = 0;
  est_ = PassiveEstimate{};
}

void PassiveLoadDrift::tick(double t, double dt, bool slide, double fhat_n, int dir, double pos_m,
                            double accel_force_n) noexcept {
  updated_ = false;
  in_stretch_ = true;
  if (win_s_ == 0) win_t0_ = t;
  win_s_ += dt;
  if (ref_frozen_) fc_s_ += dt;
  const bool ends = !slide || (b_n_ > 0 && dir != b_dir_);
  if (ends) {
    close_block();
    end_slide();
  }
  if (slide) {
    if (b_n_ == 0) b_t_ = b_p_ = b_f_ = b_s_ = b_a_ = 0, b_dir_ = dir, b_p_first_ = pos_m;
    b_p_last_ = pos_m;
    b_t_ += t, b_p_ += pos_m, b_f_ += fhat_n, b_s_ += dt, b_a_ += accel_force_n, ++b_n_;
    if (b_s_ + 0.5 * dt >= s_.block_s) close_block();
  }
  if (win_s_ >= s_.window_s) close_window();
}

/// A block cut short by a stop keeps its ticks if it is at least half a block long: in force
/// control against a stiff load the slides are short, and they are where the load shows.
void PassiveLoadDrift::close_block() noexcept {
  const int n = b_n_;
  b_n_ = 0;
  if (n == 0 || b_s_ < 0.5 * s_.block_s || n_blocks_ >= kMaxBlocks) return;
  if (std::abs(b_a_ / n) > s_.max_accel_force_n) return;
  const double p = b_p_ / n;
  const double ref = ref_n_ > 0 ? reference_at(p, b_dir_) : kNaN;
  const double travel_m = std::abs(b_p_last_ - b_p_first_);
  blocks_[n_blocks_++] = {b_t_ / n, p, b_f_ / n, ref, b_dir_, travel_m, b_s_, kNaN};
  slide_s_ += b_s_;
  seen_ = true;
}

/// A slide that ends in a creep to its stop: its last blocks, after one that travelled at least
/// creep_travel_m, travel less. There the nut sits within a few encoder counts for a block, so
/// the phase's quantization (up to half a count times the coupling's stiffness: newtons) is not
/// averaged out, and a force loop stops at the same balance every cycle, so its error repeats:
/// compared with cells a faster slide mapped there, it reads as a gain (DriftForceLoop: −0.5 N
/// in the last blocks of the 12 → 8 N slide, α ≈ −0.2 every cycle). A slide that is slow all
/// along (a ramp) stops nowhere in particular and keeps its blocks. Only the window's own blocks
/// are trimmed: a creep after a window closed mid-slide stays (a slide of a held step is
/// shorter than a window, so that is the rare case).
void PassiveLoadDrift::end_slide() noexcept {
  int last_fast = -1;
  for (int i = slide_first_; i < n_blocks_; ++i)
    if (blocks_[i].travel_m >= s_.creep_travel_m) last_fast = i;
  if (last_fast >= 0) {
    for (int i = last_fast + 1; i < n_blocks_; ++i) slide_s_ -= blocks_[i].span_s;
    n_blocks_ = last_fast + 1;
  }
  slide_first_ = n_blocks_;
}

void PassiveLoadDrift::end_stretch() noexcept {
  updated_ = false;
  close_block();
  end_slide();
  if (n_blocks_ > 0) close_window();
  win_s_ = 0;
  if (in_stretch_) ++stretch_, in_stretch_ = false;
}

/// Before the reference is complete an accepted window's blocks go into the map; after it, the
/// window is compared with the map where it revisits mapped positions, and positions the map
/// does not hold yet are mapped from their first compared visit, in the map's frame (as a
/// condition first met after a reference takes its first pass as its baseline).
void PassiveLoadDrift::close_window() noexcept {
  const double span_s = win_s_, slide_s = slide_s_;
  const Fit own = fit(false), cmp = compare_window();
  win_s_ = slide_s_ = 0;
  if (own.ok || cmp.ok) used_s_ += slide_s;
  if (!ref_frozen_) {
    if (own.ok) reference_window(cmp, span_s);
  } else if (cmp.ok) {
    map_window(cmp);
    add_window(cmp);
    est_.window_s = span_s;
  }
  n_blocks_ = 0, slide_first_ = 0;
}

/// The window compared with the map. Within the stretch the map began in, at the same positions.
/// A later stretch may press the load with its anchor moved (a hand segment in between): the
/// same force, and so the same phase and the same model error, then lies at another position.
/// The window is compared at the shift of position that fits it best (least residual variance of
/// a comparison that passes the passive-load test and uses at least half of the window's
/// blocks), searched in map cells over the whole stroke either way (free moves in between carry
/// the nut, and so the anchor, anywhere in the stroke; a search narrower than the anchor's move
/// finds a wrong shift that still passes the passive-load test: `mixed-moves` read α ≈ −2 and
/// warned falsely with a quarter of the stroke); at no shift it is the comparison at the same
/// positions. The shift is the moved anchor, so it stands for the
/// window's own offset c: on a linear load a shift and an offset are the same, and both free would
/// leave the shift undetermined (the least variance picked among equals, its variance too low).
PassiveLoadDrift::Fit PassiveLoadDrift::compare_window() noexcept {
  shift_m_ = 0;
  if (ref_n_ == 0 || stretch_ == map_stretch_) return fit(true);
  const int reach = static_cast<int>((s_.stroke_max_m - s_.stroke_min_m) / s_.bin_m);
  Fit best;
  double best_shift = 0;
  const auto scan = [&](double from_m, double step_m, int steps) {
    for (int k = 0; k <= steps; ++k) {
      shift_m_ = from_m + k * step_m;
      set_refs();
      const Fit f = fit(true);
      if (f.ok && 2 * f.m >= n_blocks_ && (!best.ok || f.var_res < best.var_res))
        best = f, best_shift = shift_m_;
    }
  };
  scan(-reach * s_.bin_m, s_.bin_m, 2 * reach);
  // Then to a tenth of a cell around the best (the map interpolates between cells): a cell of a
  // stiff load is a force step of its own.
  if (best.ok) scan(best_shift - s_.bin_m, 0.1 * s_.bin_m, 20);
  shift_m_ = best_shift;
  set_refs();
  if (!best.ok) return best;
  set_slopes();  // once, at the shift found: the scan needs only the reference itself
  return with_shift_variances(best);
}

/// The shift was fitted too (the least residual variance), so the window's gain and step are
/// known only jointly with it: their variances are those of the fit linearized in the shift as
/// well (its column −∂F̂_ref/∂p, the profile's curvature at the best shift), not of the fit with
/// the shift held. A window whose few blocks span little of the load trades gain for shift and
/// counts little; on a linear load the shift's column is the offset's. Where the joint fit does
/// not resolve the gain (gain and shift not separable in the window), it is no evidence.
PassiveLoadDrift::Fit PassiveLoadDrift::with_shift_variances(Fit best) const noexcept {
  const Fit joint = fit(true, true);
  if (!joint.ok) return Fit{};
  best.var_gain = joint.var_gain, best.var_step = joint.var_step;
  return best;
}

/// The reference at each block's position in the map's frame.
void PassiveLoadDrift::set_refs() noexcept {
  for (int i = 0; i < n_blocks_; ++i)
    blocks_[i].ref = reference_at(blocks_[i].p - shift_m_, blocks_[i].dir);
}

/// The reference's slope at each block's position in the map's frame (a central difference over
/// a cell either side; one-sided at the map's edge), after set_refs at the same shift.
void PassiveLoadDrift::set_slopes() noexcept {
  const double h = s_.bin_m;
  for (int i = 0; i < n_blocks_; ++i) {
    Block& b = blocks_[i];
    const double q = b.p - shift_m_;
    const double lo = reference_at(q - h, b.dir), hi = reference_at(q + h, b.dir);
    b.dref = std::isfinite(lo) && std::isfinite(hi) ? (hi - lo) / (2 * h)
             : std::isfinite(hi)                    ? (hi - b.ref) / h
                                                    : (b.ref - lo) / h;
  }
}

/// The map must predict later visits, in both directions, before it is the reference: once it
/// holds reference_s of windows, the next window that revisits it in both directions checks it,
/// with the margin a warning needs (beyond sigmas standard errors and beyond the minimum change,
/// at zero load and at the rated force): a map whose own check would warn is no reference. A map
/// that fails (a load that changed on its own, a motion unlike the one mapped) is dropped and
/// mapping starts again from the failing window.
void PassiveLoadDrift::reference_window(const Fit& cmp, double span_s) noexcept {
  const bool ready = ref_s_ >= s_.reference_s && ref_n_ >= 2;
  if (ready && cmp.ok && cmp.has_step) {
    const double m = s_.min_change * s_.rated_n;
    const bool agrees = std::abs(cmp.gain) * s_.rated_n <=
                            std::max(s_.sigmas * std::sqrt(cmp.var_gain) * s_.rated_n, m) &&
                        std::abs(cmp.step) <= std::max(s_.sigmas * std::sqrt(cmp.var_step), m);
    if (!agrees) {
      map_.fill(Cell{});
      ref_s_ = ref_t_sum_ = 0, ref_n_ = 0;
      for (int i = 0; i < n_blocks_; ++i) blocks_[i].ref = kNaN;
    }
    ref_frozen_ = agrees;
  }
  // A window of a later stretch than the map's first (the anchor may have moved in between) is
  // mapped only in the map's frame: its own offset and step taken out, not its gain (that is
  // what the check checks); one that cannot be compared is not mapped.
  Fit frame{};
  if (ref_n_ > 0 && stretch_ != map_stretch_) {
    if (!cmp.ok) return;
    frame = cmp, frame.gain = 0;
  }
  if (ref_n_ == 0) map_stretch_ = stretch_;
  map_window(frame);
  ref_s_ += span_s, ref_t_sum_ += win_t0_ + 0.5 * span_s, ++ref_n_;
  if (ref_frozen_) ref_t_ = ref_t_sum_ / ref_n_;
}

int PassiveLoadDrift::bin_of(double p) const noexcept {
  return std::clamp(static_cast<int>(std::floor((p - s_.stroke_min_m) / s_.bin_m)), 0, kBins - 1);
}

/// Maps the window's blocks that the map does not hold yet. cmp: the window's comparison with the
/// reference (none while the reference forms): its offset, gain and step are taken out first, so
/// every cell is in the reference's frame. A load whose anchor moved between stretches (a hand
/// segment in between) would otherwise leave cells of two anchors side by side, and a later
/// window spanning both would read the jump between them as a gain.
void PassiveLoadDrift::map_window(const Fit& cmp) noexcept {
  const auto in_frame = [&](const Block& b) {
    return (b.f - cmp.offset - cmp.step * b.dir) / (1.0 + cmp.gain);
  };
  for (int i = 0; i < n_blocks_; ++i) {
    const Block& b = blocks_[i];
    if (std::isfinite(b.ref)) continue;  // compared, not mapped again
    Cell& c = map_[(b.dir > 0 ? kBins : 0) + bin_of(b.p - shift_m_)];
    c.sum_p += b.p - shift_m_, c.sum_f += in_frame(b), ++c.n;
    if (i > 0 && !std::isfinite(blocks_[i - 1].ref)) span_slide(blocks_[i - 1], b, in_frame);
  }
}

/// Two blocks of one slide (one direction, one block after the other): the nut passed through
/// the load between them, so the empty cells between their positions take the line between the
/// two. A fast slide (the loop landing a force step at tens of mm/s) maps one block every few
/// cells; without this a later visit, whose blocks fall in between, finds no reference there
/// (the map interpolates only across two cells) and a window of a few slides is never compared.
template <class F>
void PassiveLoadDrift::span_slide(const Block& a, const Block& b, const F& in_frame) noexcept {
  if (a.dir != b.dir || b.t - a.t > 1.5 * s_.block_s) return;
  const double pa = a.p - shift_m_, pb = b.p - shift_m_, fa = in_frame(a), fb = in_frame(b);
  const int lo = bin_of(std::min(pa, pb)), hi = bin_of(std::max(pa, pb)),
            off = b.dir > 0 ? kBins : 0;
  for (int k = lo + 1; k < hi; ++k) {
    Cell& c = map_[off + k];
    if (c.n > 0) continue;
    const double p = s_.stroke_min_m + (k + 0.5) * s_.bin_m;
    c.sum_p = p, c.sum_f = fa + (fb - fa) * (p - pa) / (pb - pa), c.n = 1;
  }
}

/// The reference's F̂ at p in direction dir: interpolated between the nearest mapped cells on
/// either side within two cells (NaN where the reference did not go).
double PassiveLoadDrift::reference_at(double p, int dir) const noexcept {
  const int b = bin_of(p), off = dir > 0 ? kBins : 0;
  double p_lo = -1e9, f_lo = kNaN, p_hi = 1e9, f_hi = kNaN;
  for (int k = std::max(0, b - 2); k <= std::min(kBins - 1, b + 2); ++k) {
    const Cell& c = map_[off + k];
    if (c.n == 0) continue;
    const double pc = c.sum_p / c.n, fc = c.sum_f / c.n;
    if (pc <= p && pc > p_lo) p_lo = pc, f_lo = fc;
    if (pc >= p && pc < p_hi) p_hi = pc, f_hi = fc;
  }
  if (std::isnan(f_lo) || std::isnan(f_hi)) return kNaN;
  if (p_hi - p_lo <= 0) return f_lo;
  return f_lo + (f_hi - f_lo) * (p - p_lo) / (p_hi - p_lo);
}

/// Least squares over the window's blocks of y = c + θ₁·q + θ₂·dir, with
///   before the reference: y = F̂, q = p − p̄ (the load's apparent stiffness);
///   after it: y = F̂ − F̂_ref, q = F̂_ref on blocks where the reference went (θ₁ = α, θ₂ = −Δ₀).
/// A window that moved in one direction only (a ramp, a step) gives θ₁ alone, from its main
/// direction's blocks. Accepted where the data support a passive load: the fit predicts the
/// mean of each direction in each half of the window (by time) within sigmas of its standard
/// error (sd/√n); a load that changes on its own — a hand, an anchor that moves — leaves a part
/// off the line. Before the reference the stiffness must also be resolved (a load to compare).
PassiveLoadDrift::Fit PassiveLoadDrift::fit(bool compare, bool joint) const noexcept {
  Fit f;
  const Design d = design(compare, joint);
  f.has_step = d.has_step;
  if (d.m < 2 * d.params()) return f;
  std::array<Vec, kP> a{}, inv{};
  Vec rhs{}, th{};
  for (int i = 0; i < n_blocks_; ++i) {
    if (!d.used(blocks_[i])) continue;
    double y = 0;
    const Vec x = d.row(blocks_[i], y);
    for (int r = 0; r < kP; ++r) {
      rhs[r] += x[r] * y;
      for (int c = 0; c < kP; ++c) a[r][c] += x[r] * x[c];
    }
  }
  if (!d.has_step) a[2][2] = 1.0;  // the step's column is empty: θ₂ = 0, decoupled
  // The shift of position stands for the offset (see compare_window): c = 0. Not in the joint
  // fit, where the shift's own column takes c's place.
  if ((d.shifted && !d.joint) || d.anchored) {
    a[0] = Vec{1.0, 0.0, 0.0}, rhs[0] = 0.0;
    a[1][0] = a[2][0] = 0.0;
  }
  if (!solve_normal(a, rhs, th, inv)) return f;
  double rss = 0;
  for (int i = 0; i < n_blocks_; ++i) {
    if (d.used(blocks_[i])) rss += std::pow(residual(d, th, blocks_[i]), 2);
  }
  const double var = rss / (d.m - d.params());
  f.var_res = var, f.m = d.m;
  f.offset = th[0], f.gain = th[1], f.step = th[2], f.var_gain = var * inv[1][1],
  f.var_step = var * inv[2][2];
  f.ok = f.var_gain > 0 && (compare || std::abs(f.gain) > s_.sigmas * std::sqrt(f.var_gain)) &&
         parts_on_line(d, th, std::sqrt(var));
  return f;
}

/// The blocks a fit uses: before the reference all, after it those where the reference went;
/// of one direction only where the other has too few to resolve the step. Such a window compared
/// within the map's own stretch is anchored: the load is where the map found it (the premise of
/// the map itself: the same force at the same position), so its offset is zero and its intercept
/// is the step, −Δ₀·dir. A PLC that steps the force and holds slides one way at each step for a
/// fraction of a second; with an offset of its own no such window resolved the step, the map was
/// never checked, and live force control formed no reference in 150 s. A window that went both
/// ways keeps its own offset (an anchor that creeps within a stretch is no drift).
PassiveLoadDrift::Design PassiveLoadDrift::design(bool compare, bool joint) const noexcept {
  Design d;
  d.compare = compare;
  d.shifted = compare && ref_n_ > 0 && stretch_ != map_stretch_;
  d.joint = joint && d.shifted;
  int n_pos = 0, n_all = 0;
  for (int i = 0; i < n_blocks_; ++i) {
    if (compare && !std::isfinite(blocks_[i].ref)) continue;
    if (d.joint && !std::isfinite(blocks_[i].dref)) continue;
    ++n_all, n_pos += blocks_[i].dir > 0 ? 1 : 0, d.p_mean += blocks_[i].p;
  }
  d.has_step = n_pos >= kP && n_all - n_pos >= kP;
  d.only = d.has_step ? 0 : (2 * n_pos >= n_all ? 1 : -1);
  d.m = d.has_step ? n_all : (d.only > 0 ? n_pos : n_all - n_pos);
  d.anchored = compare && !d.shifted && !d.has_step;
  if (d.anchored) d.has_step = true;
  if (n_all > 0) d.p_mean /= n_all;
  return d;
}

double PassiveLoadDrift::residual(const Design& d, const Vec& th, const Block& b) noexcept {
  double y = 0;
  const Vec x = d.row(b, y);
  return y - th[0] * x[0] - th[1] * x[1] - th[2] * x[2];
}

/// The passive-load test: the mean residual of each direction in each half of the window (by
/// time) within sigmas of its standard error (sd/√n, the blocks taken as independent).
bool PassiveLoadDrift::parts_on_line(const Design& d, const Vec& th, double sd) const noexcept {
  std::array<double, 4> sum{};
  std::array<int, 4> cnt{};
  const double t_mid = 0.5 * (blocks_[0].t + blocks_[n_blocks_ - 1].t);
  for (int i = 0; i < n_blocks_; ++i) {
    if (!d.used(blocks_[i])) continue;
    const int g = (blocks_[i].dir > 0 ? 2 : 0) + (blocks_[i].t >= t_mid ? 1 : 0);
    sum[g] += residual(d, th, blocks_[i]), ++cnt[g];
  }
  for (int g = 0; g < 4; ++g) {
    if (cnt[g] > 0 && std::abs(sum[g] / cnt[g]) > s_.sigmas * sd / std::sqrt(double(cnt[g])))
      return false;
  }
  return true;
}

/// One window compared with the reference, into means weighted by forgetting (force-control
/// time) and by the window's own variance (a window of a few slides counts less than a sweep).
void PassiveLoadDrift::add_window(const Fit& f) noexcept {
  disp_gain_.add(f.gain, f.var_gain);
  gain_.add(fc_s_, s_.memory_s, f.gain, f.var_gain);
  if (f.has_step && f.var_step > 0) {
    disp_step_.add(f.step, f.var_step);
    step_.add(fc_s_, s_.memory_s, f.step, f.var_step);
  }
  evaluate();
  updated_ = true;
}

/// The change since the reference: α = g_ref / g − 1 ≈ −Δg, Δ₀ the estimate's error at zero
/// load (α·F_c + ΔF_f), and at the rated force α·F_r + Δ₀. Variances: the weighted means',
/// scaled by the dispersion between successive windows where it exceeds one (windows that
/// differ more than their least squares say).
void PassiveLoadDrift::evaluate() noexcept {
  if (!(step_.w > 0)) return;  // no zero-load figure yet
  const double var_a = disp_gain_.factor() * gain_.var();
  const double var_0 = disp_step_.factor() * step_.var();
  const double alpha = gain_.mean(), fr = s_.rated_n;
  PassiveEstimate e;
  e.zero_load_n = -step_.mean(), e.zero_load_se_n = std::sqrt(var_0);
  e.rated_n = alpha * fr + e.zero_load_n;
  e.rated_se_n = std::sqrt(fr * fr * var_a + var_0);
  e.gain_change = 1.0 / (1.0 + alpha) - 1.0;
  e.gain_change_se = std::sqrt(var_a) / (1.0 + alpha);
  e.scatter_measured = disp_gain_.n >= 3 && disp_step_.n >= 3;
  est_ = e;
}

}  // namespace maglead::twin
