#include "robot/espm/Flash.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <utility>

#include "core/Error.h"
#include "robot/espm/Framing.h"

namespace viscera::robot::espm {
namespace {

std::string hex(uint32_t value, int digits) {
  char text[16];
  std::snprintf(text, sizeof text, "0x%0*X", digits, value);
  return text;
}

}  // namespace

SimulatedEspmBoard::SimulatedEspmBoard(SimulatedBoardOptions options, const Packet& information)
    : options_(std::move(options)), information_(information), cells_(options_.flashBytes, 0xFF), random_(options_.seed) {
  if (!(options_.writeFailureProbability >= 0 && options_.writeFailureProbability <= 1))
    throw std::invalid_argument("SimulatedEspmBoard: the write failure probability must be in [0, 1]");
  if (options_.erasePolls < 0) throw std::invalid_argument("SimulatedEspmBoard: negative number of erase polls");
  for (const StuckBit& s : options_.stuckBits)
    if (s.address >= cells_.size() || s.bit < 0 || s.bit > 7)
      throw Error("stuck bit " + std::to_string(s.bit) + " at " + hex(s.address, 6) + " is outside the " +
                  std::to_string(cells_.size()) + "-byte flash (bits 0..7)");
}

std::vector<uint8_t> SimulatedEspmBoard::flashContent() const {
  std::vector<uint8_t> content(cells_.size());
  for (size_t a = 0; a < cells_.size(); ++a) content[a] = read(static_cast<uint32_t>(a));
  return content;
}

uint8_t SimulatedEspmBoard::read(uint32_t address) const {
  uint8_t v = cells_[address];
  for (const StuckBit& s : options_.stuckBits)
    if (s.address == address) v = static_cast<uint8_t>(s.value ? v | (1u << s.bit) : v & ~(1u << s.bit));
  return v;
}

void SimulatedEspmBoard::exchange(std::span<const uint8_t> toBoard, std::vector<uint8_t>& fromBoard) {
  // The host sends whole frames and waits for the answers, so each exchange is decoded to its end.
  const auto take = [&](const DecodedFrame& f) { handle(f, fromBoard); };
  decoder_.reset();
  decoder_.feed(toBoard, take);
  decoder_.finish(take);
}

void SimulatedEspmBoard::handle(const DecodedFrame& command, std::vector<uint8_t>& reply) {
  ++commands_;
  const uint32_t word = command.payload[0];
  if (!flashMode_) {
    // Motor feedback mode: the board only watches for the flash command.
    if ((word & 0xFF) != kCommandEnterFlash) {
      appendDissertationFrame(reply, information_);
      return;
    }
    flashMode_ = true;
  }
  const uint32_t op = word & 0xFFFF;
  const uint32_t address = command.payload[1];
  const bool addressOk = address % 2 == 0 && address + 1 < cells_.size();
  uint32_t status = 0;
  if (eraseLeft_ > 0) --eraseLeft_;
  if (eraseLeft_ > 0) {
    // Busy erasing: only reads are accepted, and they show nothing but the busy bit.
    status = kFlashReplyBusy | (op == kFlashRead || op == kCommandEnterFlash ? 0 : kFlashReplyRejected);
  } else if (op == kFlashLeave) {
    flashMode_ = false;
    appendDissertationFrame(reply, information_);
    return;
  } else if (op == kFlashErase) {
    std::fill(cells_.begin(), cells_.end(), uint8_t{0xFF});
    eraseLeft_ = options_.erasePolls;
    if (eraseLeft_ > 0) status = kFlashReplyBusy;
  } else if (op == kFlashProgram) {
    if (!addressOk) {
      status = kFlashReplyRejected;
    } else if (options_.writeFailureProbability > 0 &&
               std::bernoulli_distribution(options_.writeFailureProbability)(random_)) {
      ++dropped_;
    } else {
      // NOR programming clears bits only.
      const uint32_t data = command.payload[2];
      cells_[address] &= static_cast<uint8_t>(data >> 8);
      cells_[address + 1] &= static_cast<uint8_t>(data);
    }
  } else if (op != kFlashRead && op != kCommandEnterFlash) {
    status = kFlashReplyRejected;
  }
  if (!addressOk) status |= kFlashReplyRejected;
  Quadlets answer{};
  answer[0] = kFlashReplyTag | status;
  answer[1] = address;
  if (addressOk && !(status & kFlashReplyBusy)) answer[2] = uint32_t{read(address)} << 8 | read(address + 1);
  appendDissertationFrame(reply, answer);
}

FlashProgrammer::FlashProgrammer(EspmLink& link, FlashOptions options) : link_(link), options_(options) {
  if (!(std::isfinite(options_.lineRate) && options_.lineRate > 0))
    throw std::invalid_argument("FlashProgrammer: the line rate must be a positive number");
}

FlashProgrammer::Answer FlashProgrammer::send(uint32_t command, uint32_t address, uint32_t data) {
  Quadlets q{};
  q[0] = command;
  q[1] = address;
  q[2] = data;
  out_.clear();
  appendDissertationFrame(out_, q);
  in_.clear();
  link_.exchange(out_, in_);
  ++report_.exchanges;
  report_.bytesOnLine += out_.size() + in_.size();

  Answer a;
  const auto take = [&a](const DecodedFrame& f) {
    a.received = true;
    a.flashMode = (f.payload[0] & 0xFFFF0000) == kFlashReplyTag;
    a.status = f.payload[0] & 0xFFFF;
    a.address = f.payload[1];
    a.content = static_cast<uint16_t>(f.payload[2]);
  };
  decoder_.reset();
  decoder_.feed(in_, take);
  decoder_.finish(take);
  return a;
}

FlashReport FlashProgrammer::program(std::span<const uint8_t> image) {
  report_ = {};
  Answer a;
  for (int attempt = 0; attempt < options_.maxCommandAttempts && !(a.received && a.flashMode); ++attempt)
    a = send(kCommandEnterFlash);
  if (!(a.received && a.flashMode))
    throw Error("flash programming: the board did not enter flash mode (no flash-mode answer to command 0xF1 in " +
                std::to_string(options_.maxCommandAttempts) + " tries)");

  if (options_.erase) {
    a = send(kFlashErase);
    if (a.received && (a.status & kFlashReplyRejected)) throw Error("flash programming: the board rejected the erase command");
    while (!a.received || (a.status & kFlashReplyBusy)) {
      if (report_.erasePolls >= static_cast<uint64_t>(options_.maxErasePolls))
        throw Error("flash programming: the erase did not finish after " + std::to_string(report_.erasePolls) + " polls");
      a = send(kFlashRead);
      ++report_.erasePolls;
    }
  }

  for (size_t address = 0; address < image.size(); address += 2) {
    const uint16_t word = static_cast<uint16_t>(image[address] << 8 | (address + 1 < image.size() ? image[address + 1] : 0xFF));
    const uint32_t at = static_cast<uint32_t>(address);
    bool verified = false;
    int writes = 0;
    while (!verified && writes < options_.maxWritesPerWord) {
      a = send(kFlashProgram, at, word);
      ++writes;
      if (a.received && a.flashMode && (a.status & kFlashReplyRejected))
        throw Error("flash programming: the board rejected the word at address " + hex(at, 6) +
                    " (beyond its flash, or the board was busy)");
      verified = a.received && a.flashMode && a.status == 0 && a.address == at && a.content == word;
    }
    if (!verified) {
      std::string readBack = "no answer";
      if (a.received) {
        const uint16_t differ = static_cast<uint16_t>(a.content ^ word);
        readBack = hex(a.content, 4) + " (bits " + hex(differ, 4) + " differ, first in byte " +
                   hex(differ & 0xFF00 ? at : at + 1, 6) + ")";
      }
      throw Error("flash programming: the word at address " + hex(at, 6) + " does not verify after " +
                  std::to_string(writes) + " writes: wrote " + hex(word, 4) + ", read back " + readBack);
    }
    report_.retries += static_cast<uint64_t>(writes - 1);
    report_.bytesWritten += std::min<size_t>(2, image.size() - address);
  }
  send(kFlashLeave);
  report_.lineTime = static_cast<double>(report_.bytesOnLine) * 8 / options_.lineRate;
  return report_;
}

}  // namespace viscera::robot::espm
