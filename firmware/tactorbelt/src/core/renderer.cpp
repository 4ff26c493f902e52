#include "renderer.h"

#include <math.h>

namespace tb {

float normalize_deg(float a) {
  float r = fmodf(a, 360.0f);
  if (r < 0.0f) r += 360.0f;
  if (r >= 360.0f) r = 0.0f;  // -tiny + 360 rounds up to 360
  return r;
}

float wrap_deg(float a) {
  // (-180, 180], as 180 - mod(180 - a, 360)
  return 180.0f - normalize_deg(180.0f - a);
}

bool Layout::set_even(uint8_t n) {
  if (n < 2 || n > kMaxChannels) return false;
  float angles[kMaxChannels];
  for (uint8_t k = 0; k < n; ++k) {
    angles[k] = 180.0f / static_cast<float>(n) + static_cast<float>(k) * 360.0f / static_cast<float>(n);
  }
  return set(angles, n);
}

bool Layout::set(const float* angles_deg, uint8_t n) {
  if (n < 2 || n > kMaxChannels) return false;
  float a[kMaxChannels];
  for (uint8_t k = 0; k < n; ++k) {
    if (!isfinite(angles_deg[k])) return false;
    a[k] = normalize_deg(angles_deg[k]);
  }
  float cw[kMaxChannels];
  float ccw[kMaxChannels];
  for (uint8_t k = 0; k < n; ++k) {
    cw[k] = 360.0f;
    ccw[k] = 360.0f;
    for (uint8_t j = 0; j < n; ++j) {
      if (j == k) continue;
      const float to_j = normalize_deg(a[j] - a[k]);  // clockwise from k to j
      const float from_j = normalize_deg(a[k] - a[j]);
      if (to_j < kAngleToleranceDeg || from_j < kAngleToleranceDeg) return false;
      if (to_j < cw[k]) cw[k] = to_j;
      if (from_j < ccw[k]) ccw[k] = from_j;
    }
  }
  for (uint8_t k = 0; k < n; ++k) {
    angle_[k] = a[k];
    gap_cw_[k] = cw[k];
    gap_ccw_[k] = ccw[k];
  }
  n_ = n;
  return true;
}

int Layout::tactor_at(float x) const {
  for (uint8_t k = 0; k < n_; ++k) {
    if (fabsf(wrap_deg(x - angle_[k])) < kAngleToleranceDeg) return k;
  }
  return -1;
}

void Layout::bracket(float x, uint8_t* ccw, uint8_t* cw) const {
  float best_ccw = 361.0f;
  float best_cw = 361.0f;
  *ccw = 0;
  *cw = 0;
  for (uint8_t k = 0; k < n_; ++k) {
    // distance going counter-clockwise from x to tactor k, "at" counting as 0
    float back = normalize_deg(x - angle_[k]);
    if (360.0f - back < kAngleToleranceDeg) back = 0.0f;
    if (back < best_ccw) {
      best_ccw = back;
      *ccw = k;
    }
  }
  for (uint8_t k = 0; k < n_; ++k) {
    if (k == *ccw) continue;
    const float ahead = normalize_deg(angle_[k] - angle_[*ccw]);
    if (ahead < best_cw) {
      best_cw = ahead;
      *cw = k;
    }
  }
}

void Layout::amplitudes(float x, Law law, float falloff_deg, float* out) const {
  for (uint8_t k = 0; k < n_; ++k) {
    const float signed_d = wrap_deg(x - angle_[k]);
    const float d = fabsf(signed_d);
    const float s = signed_d >= 0.0f ? gap_cw_[k] : gap_ccw_[k];
    float y = 0.0f;
    if (d < s) {
      switch (law) {
        case Law::kPaper:
          y = 1.0f - expf(-(s - d) / falloff_deg);
          break;
        case Law::kLinear:
          y = 1.0f - d / s;
          break;
        case Law::kEnergy:
          y = sqrtf(1.0f - d / s);
          break;
      }
    }
    out[k] = y < 0.0f ? 0.0f : (y > 1.0f ? 1.0f : y);
  }
}

bool Stimulus::set(const Layout& layout, const StimulusParams& p) {
  if (p.mode >= kModeCount || p.law >= kLawCount) return false;
  layout_ = &layout;
  law_ = static_cast<Law>(p.law);
  target_deg_ = static_cast<float>(p.angle_cdeg % 36000u) / 100.0f;
  const uint16_t falloff = p.falloff_cdeg < kMinFalloffCdeg ? kMinFalloffCdeg : p.falloff_cdeg;
  falloff_deg_ = static_cast<float>(falloff) / 100.0f;
  const uint16_t period = p.period_ms < kMinPeriodMs ? kMinPeriodMs : p.period_ms;
  const uint16_t max_transit = static_cast<uint16_t>((period - 1u) / 2u);
  uint16_t transit = p.transit_ms;
  if (transit < kMinTransitMs) transit = kMinTransitMs;
  if (transit > max_transit) transit = max_transit;
  period_us_ = static_cast<uint32_t>(period) * 1000u;
  transit_us_ = static_cast<float>(transit) * 1000.0f;

  const int on = layout.tactor_at(target_deg_);
  dynamic_ = p.mode == static_cast<uint8_t>(Mode::kDynamic) && on < 0;
  if (on >= 0) {
    near_ = far_ = static_cast<uint8_t>(on);
  } else {
    uint8_t ccw = 0;
    uint8_t cw = 0;
    layout.bracket(target_deg_, &ccw, &cw);
    const float d_ccw = fabsf(wrap_deg(target_deg_ - layout.angle(ccw)));
    const float d_cw = fabsf(wrap_deg(layout.angle(cw) - target_deg_));
    // at an exact midpoint the counter-clockwise tactor counts as nearer
    const bool ccw_near = d_ccw <= d_cw + kAngleToleranceDeg * 0.1f;
    near_ = ccw_near ? ccw : cw;
    far_ = ccw_near ? cw : ccw;
    const float dn = ccw_near ? d_ccw : d_cw;
    const float df = ccw_near ? d_cw : d_ccw;
    // dwell on near: (P - 2*transit) * D_f / (D_n + D_f), then on far: the rest
    const float hold_us = static_cast<float>(period_us_) - 2.0f * transit_us_;
    const float dwell_near_us = hold_us * (df / (dn + df));
    t1_us_ = dwell_near_us;
    t2_us_ = t1_us_ + transit_us_;
    t3_us_ = t2_us_ + (hold_us - dwell_near_us);
    near_deg_ = layout.angle(near_);
    // the transit goes through the target: the short way for gaps under 180
    float span = wrap_deg(layout.angle(far_) - near_deg_);
    const float through = wrap_deg(target_deg_ - near_deg_);
    if ((span > 0.0f) != (through > 0.0f)) span -= span > 0.0f ? 360.0f : -360.0f;
    span_deg_ = span;
  }
  return true;
}

float Stimulus::location(uint64_t t_us) const {
  if (!dynamic_) return target_deg_;
  const float phase = static_cast<float>(static_cast<uint32_t>(t_us % period_us_));
  float frac;
  if (phase < t1_us_) {
    frac = 0.0f;
  } else if (phase < t2_us_) {
    frac = (phase - t1_us_) / transit_us_;
  } else if (phase < t3_us_) {
    frac = 1.0f;
  } else {
    frac = 1.0f - (phase - t3_us_) / transit_us_;
  }
  frac = frac < 0.0f ? 0.0f : (frac > 1.0f ? 1.0f : frac);
  return normalize_deg(near_deg_ + span_deg_ * frac);
}

void Stimulus::amplitudes(uint64_t t_us, float* out) const {
  if (layout_ == nullptr) return;
  layout_->amplitudes(location(t_us), law_, falloff_deg_, out);
}

uint16_t amplitude_to_level(float a) {
  if (!(a > 0.0f)) return 0;  // also NaN
  if (a >= 1.0f) return 65535;
  return static_cast<uint16_t>(a * 65535.0f + 0.5f);
}

}  // namespace tb
