// Shared helpers for the host tests: fakes for the motor and link interfaces,
// and access to the test vectors and golden CSVs named on the command line.
#pragma once

#include <stdint.h>

#include <string>
#include <vector>

#include "../tactorbelt/src/core/controller.h"
#include "json.h"

namespace support {

inline const char* g_vectors_path = "test/vectors.json";
inline const char* g_vectors_ext_path = "test/vectors_ext.json";
inline const char* g_reference_dir = "../tests/data/reference";

// The parsed vectors.json (loaded once).
inline const json::Value& vectors() {
  static json::Value v = [] {
    std::string text;
    if (!json::read_file(g_vectors_path, &text)) {
      fprintf(stderr, "cannot read %s\n", g_vectors_path);
      abort();
    }
    return json::Parser(text).parse();
  }();
  return v;
}

// The parsed vectors_ext.json (hand-written vectors of the protocol extensions).
inline const json::Value& vectors_ext() {
  static json::Value v = [] {
    std::string text;
    if (!json::read_file(g_vectors_ext_path, &text)) {
      fprintf(stderr, "cannot read %s\n", g_vectors_ext_path);
      abort();
    }
    return json::Parser(text).parse();
  }();
  return v;
}

// Records every write and counts them.
class FakeMotors : public tb::MotorDriver {
 public:
  void write(const uint16_t* levels, uint8_t n) override {
    last.assign(levels, levels + n);
    ++writes;
  }
  void write_in2(uint32_t mask, uint8_t n) override {
    (void)n;
    in2 = mask;
    ++in2_writes;
  }
  std::vector<uint16_t> last;
  int writes = 0;
  uint32_t in2 = 0;
  int in2_writes = 0;
};

// Collects COBS-framed replies, like the serial link does.
class FramingSink : public tb::ReplySink {
 public:
  void send(const uint8_t* packet, size_t n) override {
    uint8_t frame[tb::kMaxFrame];
    const size_t len = tb::frame_packet(packet, n, frame, sizeof frame);
    bytes.insert(bytes.end(), frame, frame + len);
    packets.emplace_back(packet, packet + n);
  }
  void clear() {
    bytes.clear();
    packets.clear();
  }
  std::vector<uint8_t> bytes;
  std::vector<std::vector<uint8_t>> packets;
};

}  // namespace support
