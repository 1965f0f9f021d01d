// Decoding of an ESPM byte stream fed in arbitrary pieces: finds frames at any byte offset, checks
// their CRC and header, and hands each good frame to a callback.
//
// Resynchronisation: a magic whose frame fails (bad CRC, bad public header, or cut off by the end
// of the stream) costs one byte: the search goes on from the byte after that magic, not after the
// frame it announced, so a real frame inside a corrupt span is still found.
//
// Checks beyond the CRC. A 16-bit CRC passes a corrupted frame with probability 2^-16 when the
// damage is not a single burst of at most 16 bits, so a frame with a good CRC is also refused when
//  - it holds the start of another frame with a good CRC (what a frame cut short, or missing a
//    byte, looks like when the next frame follows: the next frame is the real one), and
//  - it is an information packet with a non-zero unused bit (buttons 31:28, potentiometers
//    31:18, encoders 31:25), when the decoder takes information packets (the default).
// Both are counted. What stays is damage confined to the raw quadlets of a dissertation frame
// (status, velocity, instrument id) that is not a short burst, such as a byte slipped into them:
// such a frame passes with probability 2^-16. The public framing adds 16 checked zero bits (the
// upper half of its CRC quadlet), about 2^-32.
//
// Auto framing: the decoder holds the bytes (nothing is decided or emitted) until two frames in a
// row pass under one framing and not under the other: the second frame starts right after the
// first, or after idle zero bytes only (at most kMaxIdleGap of them). It then decodes everything
// held under that framing, from the start, and keeps it. A frame of the other framing never
// passes such a pair by chance (it would need its CRC to match and the bytes after it to be idle
// or another magic), so a wrong lock, and false packets after it, are not a practical risk. While
// undecided, at most about 2 * kAutoHoldBytes are held; beyond, the oldest bytes are dropped
// (counted as skipped). When the stream ends undecided, nothing is emitted and framing() stays
// Auto.
//
// Counters: after finish(), bytesInFrames + bytesSkipped == bytesFed.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <span>
#include <vector>

#include "robot/espm/Framing.h"
#include "robot/espm/Packet.h"

namespace viscera::robot::espm {

// One good frame, as handed to the callback. The spans and the packet point into the decoder and
// are valid only during the callback.
struct DecodedFrame {
  Framing framing = Framing::Dissertation;  // Dissertation or Public
  uint64_t offset = 0;                      // stream offset of the frame's magic
  uint32_t size = 0;                        // bytes of the whole frame
  uint16_t page = 0;                        // public framing's page (0 for the dissertation framing)
  std::span<const uint32_t> payload;        // the payload quadlets (32 for the dissertation framing)
  const Packet* packet = nullptr;           // the decoded information packet, when the frame is one
};

struct DecoderStats {
  uint64_t bytesFed = 0;
  uint64_t framesOk = 0;            // good frames emitted
  uint64_t packets = 0;             // of them, information packets (dissertation, or public page 0 length 32)
  uint64_t crcFailures = 0;         // magics whose frame had a wrong CRC
  uint64_t badHeaders = 0;          // magics whose public header was invalid
  uint64_t rejectedOverlap = 0;     // good CRC, but holding the start of another good frame
  uint64_t rejectedUnusedBits = 0;  // good CRC, but an information packet with unused bits set
  uint64_t truncatedFrames = 0;     // 1 when the stream ended inside a frame, at finish()
  uint64_t bytesInFrames = 0;       // bytes of the good frames
  uint64_t bytesSkipped = 0;        // every other byte decided so far (garbage, idle, failed frames)
};

class StreamDecoder {
 public:
  using Callback = std::function<void(const DecodedFrame&)>;

  // Zero bytes allowed between the two frames that decide an Auto framing (1 MiB: 0.42 s of line).
  static constexpr size_t kMaxIdleGap = size_t{1} << 20;
  // Bytes held at most while an Auto framing is undecided (4 MiB: 1.7 s of line at 20 Mbit/s).
  static constexpr size_t kAutoHoldBytes = size_t{4} << 20;

  // `informationPackets`: the stream is the arm's (dissertation frames and public page 0, length
  // 32 frames are information packets: decoded, and refused with unused bits set). false: frames
  // are only quadlets (the flash-programming link, whose frames are commands and answers).
  explicit StreamDecoder(Framing framing = Framing::Auto, bool informationPackets = true);

  // Decodes `size` more bytes of the stream; every frame decided by them goes to `onFrame`, in
  // stream order. Bytes that may still start a frame are kept for the next call; a frame is
  // decided once the 3 bytes after it have arrived (a frame starting inside it would show there).
  void feed(const uint8_t* data, size_t size, const Callback& onFrame);
  void feed(std::span<const uint8_t> bytes, const Callback& onFrame) { feed(bytes.data(), bytes.size(), onFrame); }
  // The end of the stream: decides the bytes still held (a frame cut off by the end counts as
  // truncated, and the search goes on after its magic). After finish() the decoder takes no more
  // bytes until reset().
  void finish(const Callback& onFrame);
  // Back to a fresh decoder with the same requested framing.
  void reset();

  const DecoderStats& stats() const { return stats_; }
  Framing requestedFraming() const { return requested_; }
  // The framing in use: the requested one, or for Auto the one decided (Auto while undecided).
  Framing framing() const { return framing_; }
  bool finished() const { return finished_; }

 private:
  // Decides the frames in data[0, n) (stream offset decided_) under framing_; returns how many
  // bytes were decided. Unless `final`, bytes that may begin an incomplete frame are left.
  size_t scan(const uint8_t* data, size_t n, bool final, const Callback& onFrame);
  // Auto framing: looks for the frame pair that decides the framing in the held bytes.
  void probe(bool final);
  enum class LockResult { Locked, NotHere, NeedMore };
  enum class Verdict { Accept, Overlap, UnusedBits, NeedMore };
  // The checks beyond the CRC of the frame with a good CRC at data[magic].
  Verdict judge(const uint8_t* data, size_t n, size_t magic, const FrameCheck& check, bool final) const;
  bool isPacket(const FrameCheck& check) const;
  // Whether the frame at `frame` is an information packet with a non-zero unused bit.
  bool hasUnusedBits(const uint8_t* frame, const FrameCheck& check) const;
  LockResult tryLock(const uint8_t* data, size_t n, size_t magic, bool final);
  void emit(const uint8_t* frame, const FrameCheck& check, uint64_t offset, const Callback& onFrame);
  void decideHeld(bool final, const Callback& onFrame);

  Framing requested_;
  Framing framing_;
  bool informationPackets_;
  DecoderStats stats_;
  bool finished_ = false;
  uint64_t decided_ = 0;          // stream offset of held_[0]: every byte before it is decided
  std::vector<uint8_t> held_;     // bytes not decided yet
  uint64_t probeFrom_ = 0;        // Auto: stream offset where the search for a deciding pair goes on
  uint64_t probeAgainAt_ = 0;     // Auto: probe again once the held bytes reach this stream offset
  std::vector<uint32_t> payload_; // reused for every frame (up to 1023 quadlets)
  Packet packet_;
};

}  // namespace viscera::robot::espm
