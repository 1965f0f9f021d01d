// Flash-programming mode of the ESPM (dissertation Appendix I): the host writes the FPGA's
// configuration image into the arm's flash over the same link, two bytes at a time, and checks
// each word by reading it back. A simulated board (a NOR flash behind the ESPM) stands in for the
// arm in tests and studies.
//
// Both directions carry dissertation frames (magic, 32 quadlets, CRC-16). Layout of the quadlets:
//
// Host -> board, quadlet 0 is the command; unused quadlets are zero.
//   Normal (motor feedback) mode: bits 7:0 = 0xF1 enter flash mode; any other command is ignored.
//   Flash mode, bits 15:0:
//     0x0000 read     quadlet 1: byte address (even)
//     0x0020 erase    erases the whole chip (every byte 0xFF); the chip answers this command and
//                     the commands after it with the busy bit until it is done
//     0x0040 program  quadlet 1: byte address (even); quadlet 2 bits 15:0: the two bytes, the
//                     byte at the address in bits 15:8, the next in bits 7:0
//     0x00F0 leave flash mode (back to streaming information packets)
//     0x00F1 stay in flash mode (answered like a read)
// Board -> host, one frame per command frame:
//   Normal mode: an information packet (Table I-1).
//   Flash mode: quadlet 0 = 0xF1A50000 | busy (bit 0) | rejected (bit 1: unknown command, odd or
//   out-of-range address, or a command while busy); quadlet 1: the address the host sent;
//   quadlet 2 bits 15:0: the flash content there (after the command; 0 while busy). Bits 31:28
//   of quadlet 0 are set, which no information packet has (they are unused buttons bits).
//
// The flash is NOR: erasing sets every bit, programming can only clear bits (the content becomes
// old AND new), so a word that was not erased does not take a value with more ones.
#pragma once

#include <cstdint>
#include <random>
#include <span>
#include <vector>

#include "robot/espm/Packet.h"
#include "robot/espm/StreamDecoder.h"

namespace viscera::robot::espm {

inline constexpr uint32_t kCommandEnterFlash = 0xF1;
inline constexpr uint32_t kFlashRead = 0x0000;
inline constexpr uint32_t kFlashErase = 0x0020;
inline constexpr uint32_t kFlashProgram = 0x0040;
inline constexpr uint32_t kFlashLeave = 0x00F0;
inline constexpr uint32_t kFlashReplyTag = 0xF1A50000;
inline constexpr uint32_t kFlashReplyBusy = 1u << 0;
inline constexpr uint32_t kFlashReplyRejected = 1u << 1;

// The duplex line to a board: what the host sends and what comes back in answer.
class EspmLink {
 public:
  virtual ~EspmLink() = default;
  // Sends `toBoard` (whole frames) and appends to `fromBoard` the bytes the board sends in answer.
  virtual void exchange(std::span<const uint8_t> toBoard, std::vector<uint8_t>& fromBoard) = 0;
};

// A flash bit that always reads `value`, whatever is erased or programmed.
struct StuckBit {
  uint32_t address = 0;  // byte address
  int bit = 0;           // 0 (least significant) .. 7
  bool value = false;
};

struct SimulatedBoardOptions {
  size_t flashBytes = 512 * 1024;        // an EPCS4-sized configuration flash
  // Commands after an erase until it is done: the last of them is the first answered ready
  // (0: done at once).
  int erasePolls = 1000;
  double writeFailureProbability = 0;    // chance that a program command leaves the flash unchanged
  uint64_t seed = 1;                     // of those failures
  std::vector<StuckBit> stuckBits;
};

// The arm's side of the link: decodes the host's command frames and answers each with a frame.
// Its flash starts erased (0xFF) unless set through flash().
class SimulatedEspmBoard : public EspmLink {
 public:
  // `information`: the packet it answers with in normal mode. Throws viscera::Error for a stuck
  // bit outside the flash or a bit number outside 0..7, std::invalid_argument for a probability
  // outside [0, 1] or a negative number of erase polls.
  explicit SimulatedEspmBoard(SimulatedBoardOptions options = {}, const Packet& information = {});

  void exchange(std::span<const uint8_t> toBoard, std::vector<uint8_t>& fromBoard) override;

  bool inFlashMode() const { return flashMode_; }
  // The flash content as it reads (stuck bits applied).
  std::vector<uint8_t> flashContent() const;
  // The stored cells, to set an initial content.
  std::span<uint8_t> cells() { return cells_; }
  uint64_t commandsReceived() const { return commands_; }
  uint64_t programsDropped() const { return dropped_; }  // program commands that did not take

 private:
  void handle(const DecodedFrame& command, std::vector<uint8_t>& reply);
  uint8_t read(uint32_t address) const;

  SimulatedBoardOptions options_;
  Packet information_;
  std::vector<uint8_t> cells_;
  StreamDecoder decoder_{Framing::Dissertation, false};  // commands and answers, not information packets
  std::mt19937_64 random_;
  bool flashMode_ = false;
  int eraseLeft_ = 0;  // exchanges until a running erase is done
  uint64_t commands_ = 0;
  uint64_t dropped_ = 0;
};

struct FlashOptions {
  bool erase = true;                // erase the chip first
  int maxWritesPerWord = 16;        // program commands per word before giving up
  int maxErasePolls = 10'000'000;   // reads while waiting for the erase
  int maxCommandAttempts = 8;       // tries of a mode command without a proper answer
  double lineRate = 20e6;           // bit/s, for the time on the line
};

struct FlashReport {
  uint64_t bytesWritten = 0;   // image bytes programmed and verified
  uint64_t retries = 0;        // program commands beyond the first, over all words
  uint64_t erasePolls = 0;     // reads until the erase was done
  uint64_t exchanges = 0;      // command frames sent (each answered by one frame)
  uint64_t bytesOnLine = 0;    // both directions
  double lineTime = 0;         // s: bytesOnLine * 8 / lineRate (each answer follows its command)
};

// The host's side: enters flash mode, erases, programs the image two bytes at a time checking
// each word in the board's answer (the content at the address just programmed) and programming it
// again until it matches, then leaves flash mode.
class FlashProgrammer {
 public:
  explicit FlashProgrammer(EspmLink& link, FlashOptions options = {});
  // Programs `image` from address 0. An odd-sized image is padded with 0xFF (the erased value).
  // Throws viscera::Error when the board does not enter flash mode, the erase does not finish,
  // or a word does not verify after maxWritesPerWord writes (naming the word's address, the
  // value written, the value read back and the first byte whose bits differ) or is rejected.
  FlashReport program(std::span<const uint8_t> image);

 private:
  struct Answer {
    bool received = false;  // a good frame came back
    bool flashMode = false; // it is a flash-mode answer
    uint32_t status = 0, address = 0;
    uint16_t content = 0;
  };
  Answer send(uint32_t command, uint32_t address = 0, uint32_t data = 0);

  EspmLink& link_;
  FlashOptions options_;
  FlashReport report_;
  std::vector<uint8_t> out_, in_;
  StreamDecoder decoder_{Framing::Dissertation, false};  // commands and answers, not information packets
};

}  // namespace viscera::robot::espm
