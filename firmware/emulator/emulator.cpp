// The firmware core on the host: serves protocol v1 on a pseudo-terminal, with the
// motors replaced by recorded levels and the 1 kHz tick on the wall clock.
//
//   emulator [--tactors N | --tactor-angles A,B,...] [--heartbeat-ms MS]
//            [--max-on-ms MS] [--levels-log FILE] [--watchdog-ms MS] [--debug-frames]
//            [--imu bmi270|lsm9ds1|none|broken] [--wiring bridge|in1]
//
// Contract (docs/protocol.md, "The emulator"):
// - The first stdout line is the pseudo-terminal's slave path (then stdout is
//   flushed and nothing else is printed there). Diagnostics go to stderr.
// - When the host side of the pseudo-terminal closes (every opener has closed
//   it), it is treated like the USB port closing: outputs off, state idle.
// - Exits 0 on SIGTERM, SIGINT or SIGHUP, and when stdin reaches end of file if
//   stdin is a pipe, a socket or a terminal (stdin from /dev/null or a regular
//   file is ignored). On exit the outputs go off (a last levels-log line).
// - Exits 2 on a bad command line, 1 when the pseudo-terminal cannot be made.
// - Replies go through the core's SerialTx: a bounded ring of whole frames,
//   drained into the pseudo-terminal without blocking; what does not fit is
//   dropped and counted (GET_DIAG), as on the board.
// - --watchdog-ms: the core's WatchdogModel, fed by the tick and watched by a
//   thread; when it expires the emulator "resets": outputs off at once, then a
//   fresh core (power-up settings, the watchdog reset flag set).
// - --debug-frames: accepts DEBUG_HANG (0x7E), which stops the loop (no tick, no
//   reading, no feeding) until the watchdog resets it (forever without one).
// - --imu: the board's accelerometer that SENSE_START streams (firmware 1.2), simulated
//   from the ERM model of the motors (erm_model.h): bmi270 (the default; Nano 33 BLE
//   Rev2, 1600 Hz), lsm9ds1 (Rev1, 952 Hz); none: no accelerometer at all (SENSE_START
//   NAKed as unknown, like firmware 1.1); broken: an IMU that did not start (NAK 6).
//   The motors' model runs whatever --imu says (the levels drive it in device time).
// - --wiring: how the board's DRV8833 inputs are wired (docs/hardware.md): bridge (the
//   default: IN1 and IN2 per motor, so shaping brakes; INFO reports kCapShape and
//   kCapBrake) or in1 (IN2 to ground, the older wiring: shaping overdrives but coasts;
//   INFO reports kCapShape alone). The motors' model takes the signed drive.
#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include <atomic>
#include <memory>
#include <thread>

#include "../tactorbelt/src/core/controller.h"
#include "../tactorbelt/src/core/links.h"
#include "erm_model.h"

namespace {

constexpr uint16_t kPwmSteps = 800;  // what the Nano 33 BLE reports (16 MHz / 20 kHz)
constexpr int64_t kTickNs = 1000000;
constexpr int64_t kMaxLagNs = 100 * kTickNs;  // behind by more: skip ahead, do not burst

volatile sig_atomic_t g_stop = 0;
std::atomic<bool> g_hang{false};        // DEBUG_HANG received
std::atomic<bool> g_wdt_fired{false};   // the watchdog thread saw it expire
std::atomic<uint64_t> g_wdt_fired_us{0};

void on_signal(int) { g_stop = 1; }

int64_t mono_ns() {
  timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<int64_t>(ts.tv_sec) * 1000000000 + ts.tv_nsec;
}

timespec to_timespec(int64_t ns) {
  timespec ts;
  ts.tv_sec = static_cast<time_t>(ns / 1000000000);
  ts.tv_nsec = static_cast<long>(ns % 1000000000);
  return ts;
}

constexpr const char kUsage[] =
    "usage: emulator [--tactors N | --tactor-angles A,B,...] [--heartbeat-ms MS]"
    " [--max-on-ms MS] [--levels-log FILE] [--watchdog-ms MS] [--debug-frames]"
    " [--imu bmi270|lsm9ds1|none|broken] [--wiring bridge|in1]\n";

[[noreturn]] void usage_error(const char* message) {
  fprintf(stderr, "emulator: error: %s\n%s", message, kUsage);
  exit(2);
}

long parse_long(const char* text, const char* what, long lo, long hi) {
  char* end = nullptr;
  errno = 0;
  const long v = strtol(text, &end, 10);
  if (errno != 0 || end == text || *end != '\0' || v < lo || v > hi) {
    char msg[200];
    snprintf(msg, sizeof msg, "%s must be an integer in %ld..%ld, got '%s'", what, lo, hi, text);
    usage_error(msg);
  }
  return v;
}

// Records levels (and the state) as CSV: "t_us,state,level_0,...", one line at
// start, one whenever a level or the state changes, and one at exit.
class LevelsLog {
 public:
  bool open(const char* path, uint8_t n) {
    f_ = fopen(path, "w");
    if (f_ == nullptr) return false;
    fprintf(f_, "t_us,state");
    for (uint8_t k = 0; k < n; ++k) fprintf(f_, ",level_%u", k);
    fprintf(f_, "\n");
    return true;
  }
  // Writes a line when a level or the state changed since the last one (or always,
  // with force).
  void record(uint64_t t_us, const tb::Controller& c, bool force = false) {
    if (f_ == nullptr) return;
    const uint8_t n = c.channels();
    const uint8_t state = static_cast<uint8_t>(c.state());
    if (!force && written_ && state == state_ &&
        memcmp(levels_, c.levels(), n * sizeof(uint16_t)) == 0) {
      return;
    }
    written_ = true;
    state_ = state;
    memcpy(levels_, c.levels(), n * sizeof(uint16_t));
    fprintf(f_, "%llu,%u", static_cast<unsigned long long>(t_us), state);
    for (uint8_t k = 0; k < n; ++k) fprintf(f_, ",%u", levels_[k]);
    fprintf(f_, "\n");
    dirty_ = true;
  }
  // Every output off at t_us, whatever the controller holds (a watchdog reset).
  void record_off(uint64_t t_us, uint8_t n) {
    if (f_ == nullptr) return;
    written_ = true;
    state_ = 0;
    memset(levels_, 0, sizeof levels_);
    fprintf(f_, "%llu,0", static_cast<unsigned long long>(t_us));
    for (uint8_t k = 0; k < n; ++k) fprintf(f_, ",0");
    fprintf(f_, "\n");
    dirty_ = true;
  }
  void flush() {
    if (f_ != nullptr && dirty_) fflush(f_);
    dirty_ = false;
  }
  void close() {
    if (f_ != nullptr) fclose(f_);
    f_ = nullptr;
  }

 private:
  FILE* f_ = nullptr;
  bool written_ = false;
  bool dirty_ = false;
  uint8_t state_ = 0;
  uint16_t levels_[tb::kMaxChannels] = {};
};

// The device time of the controller call in progress: what the motors' model takes a
// level change's time from (MotorDriver::write carries none).
uint64_t g_call_us = 0;

// The motors: their levels drive the ERM model (the simulated IMU senses it).
class SimMotors : public tb::MotorDriver {
 public:
  explicit SimMotors(emu::ErmBank& bank) : bank_(bank) {}
  void write(const uint16_t* levels, uint8_t n) override { bank_.set_levels(g_call_us, levels, n); }
  void write_in2(uint32_t mask, uint8_t) override { bank_.set_in2(g_call_us, mask); }

 private:
  emu::ErmBank& bank_;
};

class HangHook : public tb::DebugHook {
 public:
  bool handle(const tb::Packet& p) override {
    if (p.type != tb::msg::kDebugHang || p.len != 0) return false;
    g_hang = true;
    return true;
  }
};

// Everything a reset starts afresh: the core and its TX ring. (The watchdog is
// not in here: like the WDT it outlives the reset, and its thread reads it.)
struct Device {
  Device(const tb::Layout& layout, emu::ErmBank& bank)
      : motors(bank), controller(layout, motors, kPwmSteps), tx(controller.link_counters()) {}
  SimMotors motors;
  tb::Controller controller;
  tb::SerialTx tx;
};

// Drains the TX ring into the pseudo-terminal without blocking (what the kernel
// does not take stays queued; the ring drops whole frames when full).
void drain(Device& d, int fd) {
  while (d.tx.queued() > 0) {
    const uint8_t* data = nullptr;
    const size_t n = d.tx.peek(&data);
    const ssize_t w = write(fd, data, n);
    if (w > 0) {
      d.tx.consume(static_cast<size_t>(w));
      continue;
    }
    if (w < 0 && errno == EINTR) continue;
    return;  // EAGAIN: the host is not reading; EIO: nobody has the port open
  }
}

bool stdin_is_watched() {
  struct stat st;
  if (fstat(STDIN_FILENO, &st) != 0) return false;
  return S_ISFIFO(st.st_mode) || S_ISSOCK(st.st_mode) || isatty(STDIN_FILENO);
}

}  // namespace

int main(int argc, char** argv) {
  uint8_t tactors = 6;
  float angles[tb::kMaxChannels];
  uint8_t n_angles = 0;
  long heartbeat_ms = -1;
  long max_on_ms = -1;
  const char* log_path = nullptr;
  long watchdog_ms = 0;
  bool debug_frames = false;
  const char* imu = "bmi270";
  bool wiring_bridge = true;
  for (int i = 1; i < argc; ++i) {
    const char* a = argv[i];
    const bool has_value = i + 1 < argc;
    char msg[200];
    if (strcmp(a, "--help") == 0 || strcmp(a, "-h") == 0) {
      printf("%sServes tactorbelt protocol v1 on a pseudo-terminal; prints its path first.\n"
             "See docs/protocol.md, \"The emulator\".\n", kUsage);
      return 0;
    }
    if (strcmp(a, "--debug-frames") == 0) {
      debug_frames = true;
      continue;
    }
    if (!has_value) {
      snprintf(msg, sizeof msg, "%s needs a value", a);
      usage_error(msg);
    }
    const char* v = argv[++i];
    if (strcmp(a, "--tactors") == 0) {
      tactors = static_cast<uint8_t>(parse_long(v, "--tactors", 2, tb::kMaxChannels));
    } else if (strcmp(a, "--tactor-angles") == 0) {
      n_angles = 0;
      const char* p = v;
      while (*p != '\0') {
        char* end = nullptr;
        const float deg = strtof(p, &end);
        const bool bad = end == p || n_angles == tb::kMaxChannels || (*end != ',' && *end != '\0');
        if (bad) {
          snprintf(msg, sizeof msg, "--tactor-angles takes 2..16 angles in degrees, got '%s'", v);
          usage_error(msg);
        }
        angles[n_angles++] = deg;
        p = *end == ',' ? end + 1 : end;
      }
    } else if (strcmp(a, "--heartbeat-ms") == 0) {
      heartbeat_ms = parse_long(v, "--heartbeat-ms", tb::kMinHeartbeatMs, tb::kMaxHeartbeatMs);
    } else if (strcmp(a, "--max-on-ms") == 0) {
      max_on_ms = parse_long(v, "--max-on-ms", tb::kMinMaxOnMs, tb::kMaxMaxOnMs);
    } else if (strcmp(a, "--levels-log") == 0) {
      log_path = v;
    } else if (strcmp(a, "--watchdog-ms") == 0) {
      watchdog_ms = parse_long(v, "--watchdog-ms", 0, 10000);
    } else if (strcmp(a, "--imu") == 0) {
      if (strcmp(v, "bmi270") != 0 && strcmp(v, "lsm9ds1") != 0 && strcmp(v, "none") != 0 &&
          strcmp(v, "broken") != 0) {
        snprintf(msg, sizeof msg, "--imu takes bmi270, lsm9ds1, none or broken, got '%s'", v);
        usage_error(msg);
      }
      imu = v;
    } else if (strcmp(a, "--wiring") == 0) {
      if (strcmp(v, "bridge") != 0 && strcmp(v, "in1") != 0) {
        snprintf(msg, sizeof msg, "--wiring takes bridge or in1, got '%s'", v);
        usage_error(msg);
      }
      wiring_bridge = strcmp(v, "bridge") == 0;
    } else {
      snprintf(msg, sizeof msg, "unknown option '%s'", a);
      usage_error(msg);
    }
  }

  tb::Layout layout;
  if (n_angles > 0 ? !layout.set(angles, n_angles) : !layout.set_even(tactors)) {
    usage_error("--tactor-angles needs 2..16 distinct finite angles");
  }
  HangHook hang_hook;
  tb::WatchdogModel watchdog(static_cast<uint32_t>(watchdog_ms));
  // The motors and the IMU outlive a reset, as on the board (a motor spins down).
  emu::ErmBank bank(layout.size());
  const bool imu_lsm9ds1 = strcmp(imu, "lsm9ds1") == 0;
  emu::SimImu sim_imu(bank, imu_lsm9ds1 ? 1051 : 625, strcmp(imu, "broken") != 0);
  const bool has_imu = strcmp(imu, "none") != 0;
  std::unique_ptr<Device> dev;
  // Power-up (and a watchdog reset): a fresh core with the command line's settings.
  auto boot = [&](uint64_t t_us, uint8_t reset_flags) {
    g_call_us = t_us;
    dev = std::make_unique<Device>(layout, bank);
    tb::Controller& c = dev->controller;
    if (has_imu) c.set_accelerometer(&sim_imu);
    c.set_drive_shaping(wiring_bridge);
    if (heartbeat_ms >= 0) c.set_heartbeat_ms(static_cast<uint16_t>(heartbeat_ms));
    if (max_on_ms >= 0) c.set_max_on_ms(static_cast<uint32_t>(max_on_ms));
    c.set_reset_flags(reset_flags);
    if (debug_frames) c.set_debug_hook(&hang_hook);
    if (watchdog_ms > 0) {
      c.set_watchdog(&watchdog);
      watchdog.start(t_us);
    }
    c.begin(t_us);
  };

  LevelsLog levels_log;
  if (log_path != nullptr && !levels_log.open(log_path, layout.size())) {
    fprintf(stderr, "emulator: error: cannot write %s: %s\n", log_path, strerror(errno));
    return 2;
  }

  const int master = posix_openpt(O_RDWR | O_NOCTTY);
  if (master < 0 || grantpt(master) != 0 || unlockpt(master) != 0) {
    fprintf(stderr, "emulator: error: cannot open a pseudo-terminal: %s\n", strerror(errno));
    return 1;
  }
  const char* slave_name = ptsname(master);
  if (slave_name == nullptr) {
    fprintf(stderr, "emulator: error: ptsname: %s\n", strerror(errno));
    return 1;
  }
  char slave_path[256];
  snprintf(slave_path, sizeof slave_path, "%s", slave_name);
  // Raw mode on the slave side (kept while the master is open), so the first
  // opener sees bytes, not lines, even if it does not set raw mode itself.
  const int slave = open(slave_path, O_RDWR | O_NOCTTY);
  if (slave >= 0) {
    termios tio;
    if (tcgetattr(slave, &tio) == 0) {
      cfmakeraw(&tio);
      tcsetattr(slave, TCSANOW, &tio);
    }
    close(slave);
  }
  fcntl(master, F_SETFL, fcntl(master, F_GETFL) | O_NONBLOCK);

  struct sigaction sa;
  memset(&sa, 0, sizeof sa);
  sa.sa_handler = on_signal;
  sigaction(SIGTERM, &sa, nullptr);
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGHUP, &sa, nullptr);
  signal(SIGPIPE, SIG_IGN);

  const bool watch_stdin = stdin_is_watched();
  printf("%s\n", slave_path);
  fflush(stdout);

  const int64_t t0 = mono_ns();
  auto now_us = [t0] { return static_cast<uint64_t>((mono_ns() - t0) / 1000); };
  boot(0, 0);
  levels_log.record(0, dev->controller);
  levels_log.flush();

  // The watchdog runs on its own, like the nRF52840 WDT on its 32 kHz clock.
  std::thread watchdog_thread;
  if (watchdog_ms > 0) {
    watchdog_thread = std::thread([&] {
      while (!g_stop) {
        const uint64_t t = now_us();
        if (!g_wdt_fired && watchdog.expired(t)) {
          g_wdt_fired_us = t;
          g_wdt_fired = true;
        }
        timespec ts = {0, 1000000};
        nanosleep(&ts, nullptr);
      }
    });
  }

  bool connected = false;
  int64_t next = t0 + kTickNs;
  uint8_t buf[4096];
  while (!g_stop) {
    if (g_hang) {
      // DEBUG_HANG: the loop is stuck; only the watchdog gets it out.
      drain(*dev, master);  // the ACK, so the host knows the hang began
      while (!g_stop && !g_wdt_fired) {
        timespec ts = {0, 1000000};
        nanosleep(&ts, nullptr);
      }
      g_hang = false;
    }
    if (g_wdt_fired) {
      // Watchdog reset: the pins go to inputs (driver pull-downs: motors off) at
      // the moment it fires; the firmware boots again and reports the cause.
      const uint64_t t_fire = g_wdt_fired_us;
      const uint16_t off[tb::kMaxChannels] = {};
      bank.set_levels(t_fire, off, layout.size());
      bank.set_in2(t_fire, 0);  // both inputs low
      levels_log.record_off(t_fire, layout.size());
      levels_log.flush();
      fprintf(stderr, "emulator: watchdog reset (not fed for %ld ms)\n", watchdog_ms);
      boot(now_us(), tb::reset::kWatchdog);
      dev->tx.set_open(connected);
      g_wdt_fired = false;
      next = mono_ns() + kTickNs;
      continue;
    }
    const int64_t now = mono_ns();
    // A SENSE sample due (SENSE_START): taken on time, between ticks too.
    const uint64_t sense_us = dev->controller.next_sense_us();
    const int64_t sense_ns =
        sense_us == UINT64_MAX ? INT64_MAX : t0 + static_cast<int64_t>(sense_us) * 1000;
    if (now >= sense_ns && now < next) {
      const uint64_t t = now_us();
      g_call_us = t;
      dev->controller.poll_sense(t);
      drain(*dev, master);
      continue;
    }
    if (now >= next) {
      // The 1 kHz tick, on absolute deadlines.
      if (now - next > kMaxLagNs) next = now;  // suspended or starved: skip, do not burst
      next += kTickNs;
      const uint64_t t = now_us();
      g_call_us = t;
      dev->controller.poll_sense(t);  // samples due before the tick changes the levels
      dev->controller.tick(t);
      dev->controller.poll_sense(t);
      if (!connected) {
        // Without an opener the master reports POLLHUP at once, so it is not
        // waited on; look for an opener once per tick instead.
        pollfd p = {master, POLLIN, 0};
        if (poll(&p, 1, 0) >= 0 && !(p.revents & POLLHUP)) connected = true;
        dev->tx.set_open(connected);
      }
      drain(*dev, master);
      levels_log.record(t, dev->controller);
      levels_log.flush();
      continue;
    }
    // Between ticks: wait for a request (served at once) or the next deadline.
    pollfd fds[2];
    nfds_t nfds = 0;
    int master_i = -1;
    int stdin_i = -1;
    if (connected) {
      master_i = static_cast<int>(nfds);
      fds[nfds++] = {master, POLLIN, 0};
    }
    if (watch_stdin) {
      stdin_i = static_cast<int>(nfds);
      fds[nfds++] = {STDIN_FILENO, POLLIN, 0};
    }
    const timespec timeout = to_timespec((sense_ns < next ? sense_ns : next) - now);
    const int ready = ppoll(fds, nfds, &timeout, nullptr);
    if (ready < 0 && errno != EINTR) break;
    if (ready <= 0) continue;
    const uint64_t t = now_us();
    g_call_us = t;
    if (master_i >= 0 && fds[master_i].revents != 0) {
      if (fds[master_i].revents & POLLIN) {
        dev->controller.poll_sense(t);  // samples due before a request changes the levels
        dev->controller.tick(t);  // outputs as of now, so that a STATUS reports them
        while (!g_hang) {
          const ssize_t r = read(master, buf, sizeof buf);
          if (r > 0) {
            dev->controller.receive_bytes(buf, static_cast<size_t>(r), t, dev->tx);
            drain(*dev, master);
            continue;
          }
          if (r < 0 && errno == EINTR) continue;
          break;  // EAGAIN: drained; EIO: no opener any more (POLLHUP)
        }
        dev->controller.poll_sense(t);  // a SENSE_START's first sample, at once
        drain(*dev, master);
      }
      if (fds[master_i].revents & (POLLHUP | POLLERR)) {
        // every opener closed the port: like the USB port closing
        dev->controller.link_closed(t);
        tcflush(master, TCIOFLUSH);
        connected = false;
        dev->tx.set_open(false);
      }
      levels_log.record(t, dev->controller);
      levels_log.flush();
    }
    if (stdin_i >= 0 && (fds[stdin_i].revents & (POLLIN | POLLHUP | POLLERR))) {
      const ssize_t r = read(STDIN_FILENO, buf, sizeof buf);
      if (r == 0 || (r < 0 && errno != EINTR && errno != EAGAIN)) break;  // end of file: exit
    }
  }

  g_stop = 1;
  if (watchdog_thread.joinable()) watchdog_thread.join();
  const uint64_t t = now_us();
  g_call_us = t;
  dev->controller.link_closed(t);
  levels_log.record(t, dev->controller, true);
  levels_log.flush();
  levels_log.close();
  close(master);
  return 0;
}
