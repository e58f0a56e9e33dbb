// Benchmark: decoding serial gyro frames (the KVH 1775 Format A example: 36 bytes, CRC-32/MPEG-2,
// float32 rate, 7-bit counter) in memory, 4096-byte reads as from a tty, with one garbage run and
// one corrupted frame every 1000 frames. Two figures: the pure decoder (serial::Decoder) and the
// whole serial path the transport runs per frame (decoder, counts, sequence mapping, CAN encode,
// SampleAccumulator), each in frames/s on one core, and the share of a core the load
// (8 units x 3 axes x 1,000 frames/s = 24,000 frames/s) takes.
#include <nlohmann/json.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <fstream>
#include <vector>

#include "fogbench/drivers/can_frame.hpp"
#include "fogbench/drivers/sample_accumulator.hpp"
#include "fogbench/drivers/serial_frame.hpp"

using namespace fogbench::drivers;

namespace {

double cpu_s() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + static_cast<double>(ts.tv_nsec) * 1e-9;
}

}  // namespace

int main() {
  std::ifstream in(FOGBENCH_SOURCE_DIR "/drivers/examples/kvh-1775-format-a.json");
  auto format = serial::parse_frame_format(nlohmann::json::parse(in), "frame");
  if (!format) {
    std::fprintf(stderr, "%s\n", format.error().message.c_str());
    return 1;
  }
  constexpr int frames = 200000;
  std::vector<std::uint8_t> stream;
  stream.reserve(static_cast<std::size_t>(frames) * 40);
  for (int i = 0; i < frames; ++i) {
    auto f = serial::encode(*format, {.rate_dph = 10.0 + 0.001 * (i % 97), .sequence = static_cast<std::uint32_t>(i),
                                      .status = 0x77, .valid = true});
    if (i % 1000 == 500) f[12] ^= 0x10;                                 // a CRC error
    if (i % 1000 == 700) stream.insert(stream.end(), {0x00, 0x13, 0xFE});  // garbage
    stream.insert(stream.end(), f.begin(), f.end());
  }
  const std::size_t chunk = 4096;
  constexpr int rounds = 5;

  double best_decoder = 0;
  std::uint64_t good = 0;
  for (int r = 0; r < rounds; ++r) {
    serial::Decoder d(*format);
    std::vector<serial::Event> events;
    events.reserve(256);
    const double t0 = cpu_s();
    for (std::size_t at = 0; at < stream.size(); at += chunk) {
      events.clear();
      d.feed(std::span<const std::uint8_t>(stream.data() + at, std::min(chunk, stream.size() - at)), events);
    }
    const double fps = static_cast<double>(frames) / (cpu_s() - t0);
    best_decoder = std::max(best_decoder, fps);
    good = d.counts().frames;
  }

  double best_path = 0;
  GyroSample sample;
  for (int r = 0; r < rounds; ++r) {
    serial::Decoder d(*format);
    serial::SequenceMapper seq(format->sequence_modulo);
    GyroChannelConfig unit;
    unit.node_id = 0x101;
    unit.scale_dph_per_count = 1e-4;
    SampleAccumulator acc(unit);
    std::vector<serial::Event> events;
    events.reserve(256);
    const double t0 = cpu_s();
    for (std::size_t at = 0; at < stream.size(); at += chunk) {
      events.clear();
      d.feed(std::span<const std::uint8_t>(stream.data() + at, std::min(chunk, stream.size() - at)), events);
      for (const auto& e : events) {
        if (e.kind == serial::Event::Kind::bad_crc || e.kind == serial::Event::Kind::cut) {
          ::can_frame corrupt{};
          corrupt.can_id = unit.node_id;  // DLC 0: counted corrupt, as the transport does
          acc.add(corrupt);
          continue;
        }
        if (e.kind != serial::Event::Kind::frame) continue;
        can::GyroFrame f;
        f.node_id = unit.node_id;
        f.counts = static_cast<std::int32_t>(std::nearbyint(e.frame.rate_dph / unit.scale_dph_per_count));
        f.sequence = seq.map(e.frame.sequence);
        f.status = e.frame.valid ? can::status::valid : 0;
        acc.add(can::encode(f));
      }
    }
    const double fps = static_cast<double>(frames) / (cpu_s() - t0);
    best_path = std::max(best_path, fps);
    sample = acc.close();
  }
  const double load = 8 * 3 * 1000.0;
  std::printf("serial decode, KVH 1775 Format A (36 B, CRC-32/MPEG-2), %d frames, 4096-byte reads, best of %d:\n",
              frames, rounds);
  std::printf("  decoder alone:        %.3g frames/s per core (%.2f %% of a core at 24,000 frames/s)\n", best_decoder,
              100.0 * load / best_decoder);
  std::printf("  decoder + accounting: %.3g frames/s per core (%.2f %% of a core at 24,000 frames/s)\n", best_path,
              100.0 * load / best_path);
  std::printf("  good %llu, last sample: frames %u corrupt %u lost %u\n", static_cast<unsigned long long>(good),
              sample.frames, sample.frames_corrupt, sample.frames_lost);
  return 0;
}
