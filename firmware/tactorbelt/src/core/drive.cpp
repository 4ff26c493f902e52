#include "drive.h"

#include <math.h>

namespace tb {

namespace {

// exp(-x) for x >= 0, 0 past the float range (as erm.py caps the decay exponent).
float decay(float x) { return x >= 80.0f ? 0.0f : expf(-x); }

}  // namespace

void DriveParams::prepare(float tick_s) {
  e_rise = decay(tick_s / rise_tau_s);
  e_fall = decay(tick_s / fall_tau_s);
  e_brake = decay(tick_s / brake_tau_s);
  const float tick_us = tick_s * 1e6f;
  over_bound_us = rated < 1.0f
      ? static_cast<uint32_t>(rise_tau_s * logf(1.0f / (1.0f - rated)) * 1e6f + tick_us)
      : 0u;  // rated at full duty: nothing drives above it
  reverse_bound_us = static_cast<uint32_t>(brake_tau_s * logf(2.0f) * 1e6f + tick_us);
}

Drive shape_tick(float level, float w, const DriveParams& p, bool brake) {
  const float s = level >= p.start ? level : 0.0f;
  const float gap = s - w;
  Drive d;
  d.mag = level;
  if (gap > kSettled) {
    // below the level: the kick, or on its last tick the drive that lands on s
    const float x = p.e_rise;
    d.mag = fminf((s - w * x) / (1.0f - x), 1.0f);
  } else if (gap < -kSettled) {
    const float x = p.e_fall;
    const float fwd = (s - w * x) / (1.0f - x);  // the forward drive that lands, coasting
    if (fwd >= p.start && s > 0.0f) {
      d.mag = fwd;
    } else if (brake) {
      const float xb = p.e_brake;
      const float rev = (s - w * xb) / (1.0f - xb);  // the reverse drive that lands
      if (rev <= 0.0f) {
        d.mag = fminf(-rev, 1.0f);
        d.reverse = true;
      }
    } else if (fwd < 0.0f) {
      d.mag = 0.0f;  // coast
    }
  }
  return d;
}

float drive_relax(const Drive& d, float w, float h_s, const DriveParams& p) {
  float u;
  float tau;
  if (d.reverse) {
    u = -d.mag;
    tau = p.brake_tau_s;
  } else {
    u = d.mag >= p.start ? d.mag : 0.0f;
    tau = u > w ? p.rise_tau_s : p.fall_tau_s;
  }
  return u + (w - u) * decay(h_s / tau);
}

namespace {

uint16_t to_level(float a) {
  if (!(a > 0.0f)) return 0;
  if (a >= 1.0f) return 65535;
  return static_cast<uint16_t>(a * 65535.0f + 0.5f);
}

}  // namespace

void drive_to_bridge(const Drive& d, uint16_t* in1, bool* in2) {
  if (d.reverse) {
    *in1 = static_cast<uint16_t>(65535u - to_level(d.mag));
    *in2 = true;
  } else {
    *in1 = to_level(d.mag);
    *in2 = false;
  }
}

Drive bridge_to_drive(uint16_t in1, bool in2) {
  Drive d;
  if (in2) {
    d.reverse = true;
    d.mag = static_cast<float>(65535u - in1) / 65535.0f;
  } else {
    d.mag = static_cast<float>(in1) / 65535.0f;
  }
  return d;
}

}  // namespace tb
