// The renderer against the golden CSVs (an independent implementation) and the
// amplitudes the Python package renders (vectors.json), within 2/65535.
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <string>
#include <vector>

#include "../tactorbelt/src/core/renderer.h"
#include "minitest.h"
#include "support.h"

namespace {

constexpr double kTolerance = 2.0 / 65535.0;

// Rows of numbers from a CSV with one header line.
std::vector<std::vector<double>> read_csv(const std::string& path) {
  std::string text;
  if (!json::read_file(path.c_str(), &text)) {
    fprintf(stderr, "cannot read %s\n", path.c_str());
    abort();
  }
  std::vector<std::vector<double>> rows;
  size_t pos = text.find('\n') + 1;  // skip the header
  while (pos < text.size()) {
    size_t end = text.find('\n', pos);
    if (end == std::string::npos) end = text.size();
    std::vector<double> row;
    const char* p = text.c_str() + pos;
    const char* stop = text.c_str() + end;
    while (p < stop) {
      char* next = nullptr;
      row.push_back(strtod(p, &next));
      p = next;
      if (p < stop && *p == ',') ++p;
    }
    if (!row.empty()) rows.push_back(row);
    pos = end + 1;
  }
  return rows;
}

tb::StimulusParams params(uint16_t angle_cdeg, tb::Mode mode) {
  tb::StimulusParams p;
  p.angle_cdeg = angle_cdeg;
  p.mode = static_cast<uint8_t>(mode);
  return p;
}

}  // namespace

TEST(static_golden_24_targets) {
  tb::Layout layout;
  CHECK(layout.set_even(6));
  const auto rows = read_csv(std::string(support::g_reference_dir) + "/paper_law_static_24.csv");
  CHECK_EQ(rows.size(), 24);
  for (const auto& row : rows) {
    tb::Stimulus s;
    CHECK(s.set(layout, params(static_cast<uint16_t>(row[0] * 100.0 + 0.5), tb::Mode::kStatic)));
    float amps[tb::kMaxChannels];
    s.amplitudes(0, amps);
    for (int k = 0; k < 6; ++k) CHECK_NEAR(amps[k], row[1 + k], kTolerance);
  }
}

TEST(dynamic_golden_15_and_60_degrees) {
  tb::Layout layout;
  CHECK(layout.set_even(6));
  const struct {
    const char* file;
    uint16_t cdeg;
  } cases[] = {{"/paper_law_dynamic_15deg_1000hz.csv", 1500},
               {"/paper_law_dynamic_60deg_1000hz.csv", 6000}};
  for (const auto& c : cases) {
    const auto rows = read_csv(std::string(support::g_reference_dir) + c.file);
    CHECK_EQ(rows.size(), 1000);
    tb::Stimulus s;
    CHECK(s.set(layout, params(c.cdeg, tb::Mode::kDynamic)));
    CHECK(s.dynamic());
    for (size_t i = 0; i < rows.size(); ++i) {
      float amps[tb::kMaxChannels];
      s.amplitudes(static_cast<uint64_t>(i) * 1000u, amps);
      for (int k = 0; k < 6; ++k) CHECK_NEAR(amps[k], rows[i][1 + k], kTolerance);
    }
  }
}

TEST(quarter_point_dwells_600_and_200_ms) {
  tb::Layout layout;
  CHECK(layout.set_even(6));
  tb::Stimulus s;
  CHECK(s.set(layout, params(1500, tb::Mode::kDynamic)));  // quarter point of 30..330
  CHECK_EQ(s.near_tactor(), 0);
  CHECK_EQ(s.far_tactor(), 5);
  CHECK_NEAR(s.location(0), 30.0, 1e-4);
  CHECK_NEAR(s.location(599000), 30.0, 1e-4);
  CHECK_NEAR(s.location(650000), 0.0, 1e-3);  // half way through the transit
  CHECK_NEAR(s.location(700000), 330.0, 1e-3);
  CHECK_NEAR(s.location(899000), 330.0, 1e-3);
  CHECK_NEAR(s.location(1000000), 30.0, 1e-4);  // periodic
  // midpoint: the counter-clockwise tactor is the nearer one
  CHECK(s.set(layout, params(6000, tb::Mode::kDynamic)));
  CHECK_EQ(s.near_tactor(), 0);
  CHECK_EQ(s.far_tactor(), 1);
  // on-tactor targets render static even in dynamic mode
  CHECK(s.set(layout, params(9000, tb::Mode::kDynamic)));
  CHECK(!s.dynamic());
}

TEST(stimulus_rejects_unknown_mode_and_law_and_clamps) {
  tb::Layout layout;
  CHECK(layout.set_even(6));
  tb::Stimulus s;
  tb::StimulusParams p = params(4500, tb::Mode::kDynamic);
  p.mode = 2;
  CHECK(!s.set(layout, p));
  p.mode = 1;
  p.law = 3;
  CHECK(!s.set(layout, p));
  p.law = 0;
  p.period_ms = 0;   // clamped to 10 ms
  p.transit_ms = 0;  // clamped to 1 ms
  p.falloff_cdeg = 0;
  CHECK(s.set(layout, p));
  float amps[tb::kMaxChannels];
  for (uint64_t t = 0; t < 20000; t += 250) {
    s.amplitudes(t, amps);
    for (int k = 0; k < 6; ++k) CHECK(amps[k] >= 0.0f && amps[k] <= 1.0f);
  }
  p.angle_cdeg = 36000 + 4500;  // taken modulo 360 degrees
  p.period_ms = 1000;
  p.transit_ms = 100;
  p.falloff_cdeg = 1500;
  CHECK(s.set(layout, p));
  CHECK_NEAR(s.location(0), 30.0, 1e-4);
}

TEST(layout_rejects_bad_input) {
  tb::Layout layout;
  CHECK(!layout.set_even(1));
  CHECK(!layout.set_even(tb::kMaxChannels + 1));
  const float dup[] = {10.0f, 10.0f, 200.0f};
  CHECK(!layout.set(dup, 3));
  const float nan[] = {10.0f, NAN};
  CHECK(!layout.set(nan, 2));
  const float ok[] = {370.0f, -10.0f};
  CHECK(layout.set(ok, 2));
  CHECK_NEAR(layout.angle(0), 10.0, 1e-5);
  CHECK_NEAR(layout.angle(1), 350.0, 1e-5);
}

TEST(amplitude_to_level_rounds_and_clamps) {
  CHECK_EQ(tb::amplitude_to_level(0.0f), 0);
  CHECK_EQ(tb::amplitude_to_level(-1.0f), 0);
  CHECK_EQ(tb::amplitude_to_level(NAN), 0);
  CHECK_EQ(tb::amplitude_to_level(1.0f), 65535);
  CHECK_EQ(tb::amplitude_to_level(2.0f), 65535);
  CHECK_EQ(tb::amplitude_to_level(0.5f), 32768);
  CHECK_EQ(tb::amplitude_to_level(1.0f / 65535.0f), 1);
}

TEST(render_vectors_match_python) {
  const auto& cases = support::vectors()["render"];
  CHECK(cases.size() >= 100);
  size_t samples = 0;
  double worst = 0.0;
  for (const auto& c : cases.arr) {
    const auto& angles = c["tactor_angles_deg"];
    float a[tb::kMaxChannels];
    for (size_t k = 0; k < angles.size(); ++k) a[k] = static_cast<float>(angles[k].number());
    tb::Layout layout;
    CHECK(layout.set(a, static_cast<uint8_t>(angles.size())));
    tb::StimulusParams p;
    p.angle_cdeg = static_cast<uint16_t>(c["angle_cdeg"].integer());
    p.mode = static_cast<uint8_t>(c["mode"].integer());
    p.law = static_cast<uint8_t>(c["law"].integer());
    p.falloff_cdeg = static_cast<uint16_t>(c["falloff_cdeg"].integer());
    p.period_ms = static_cast<uint16_t>(c["period_ms"].integer());
    p.transit_ms = static_cast<uint16_t>(c["transit_ms"].integer());
    tb::Stimulus s;
    CHECK(s.set(layout, p));
    const auto& times = c["t_us"];
    const auto& amps = c["amplitudes"];
    CHECK_EQ(times.size(), amps.size());
    for (size_t i = 0; i < times.size(); ++i) {
      float out[tb::kMaxChannels];
      s.amplitudes(static_cast<uint64_t>(times[i].integer()), out);
      for (size_t k = 0; k < angles.size(); ++k) {
        char ctx[160];
        // %lu, not %zu: newlib's printf on the Cortex-M4 run does not know %zu
        snprintf(ctx, sizeof ctx, "n=%lu cdeg=%d mode=%d law=%d t=%lldus tactor %lu",
                 static_cast<unsigned long>(angles.size()), p.angle_cdeg, p.mode, p.law,
                 times[i].integer(), static_cast<unsigned long>(k));
        CHECK_NEAR_CTX(out[k], amps[i][k].number(), kTolerance, ctx);
        worst = fmax(worst, fabs(static_cast<double>(out[k]) - amps[i][k].number()));
      }
      ++samples;
    }
  }
  printf("render vectors: %lu cases, %lu samples, largest difference %.2e (%.3f/65535)\n",
         static_cast<unsigned long>(cases.size()), static_cast<unsigned long>(samples), worst,
         worst * 65535.0);
}
