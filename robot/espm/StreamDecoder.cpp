#include "robot/espm/StreamDecoder.h"

#include <algorithm>
#include <cstring>
#include <stdexcept>

namespace viscera::robot::espm {
namespace {

constexpr size_t kNone = static_cast<size_t>(-1);

// First position >= pos where the 4 bytes of the magic start in data[0, n), or kNone.
size_t findMagic(const uint8_t* data, size_t n, size_t pos) {
  if (n < 4) return kNone;
  const size_t last = n - 4;
  const uint8_t first = static_cast<uint8_t>(kMagic >> 24);
  while (pos <= last) {
    if (data[pos] == first) {
      if (loadBigEndian32(data + pos) == kMagic) return pos;
      ++pos;
      continue;
    }
    const void* hit = std::memchr(data + pos + 1, first, last - pos);
    if (!hit) return kNone;
    pos = static_cast<size_t>(static_cast<const uint8_t*>(hit) - data);
  }
  return kNone;
}

}  // namespace

StreamDecoder::StreamDecoder(Framing framing, bool informationPackets)
    : requested_(framing), framing_(framing), informationPackets_(informationPackets) {
  payload_.reserve(kMaxPublicPayload);
}

void StreamDecoder::reset() {
  framing_ = requested_;
  stats_ = {};
  finished_ = false;
  decided_ = 0;
  held_.clear();
  probeFrom_ = 0;
  probeAgainAt_ = 0;
}

void StreamDecoder::feed(const uint8_t* data, size_t size, const Callback& onFrame) {
  if (finished_) throw std::logic_error("StreamDecoder::feed: the stream was finished; reset() first");
  stats_.bytesFed += size;
  if (framing_ == Framing::Auto) {
    held_.insert(held_.end(), data, data + size);
    if (decided_ + held_.size() >= probeAgainAt_) probe(false);
    if (framing_ != Framing::Auto) decideHeld(false, onFrame);
    return;
  }
  while (size > 0) {
    // Nothing held: decode in place and keep only the undecided tail (less than one frame).
    if (held_.empty()) {
      const size_t used = scan(data, size, false, onFrame);
      held_.assign(data + used, data + size);
      return;
    }
    // A frame started in an earlier piece: complete it from this one, a frame's worth at a time,
    // and go back to decoding in place once every held byte is decided.
    const size_t old = held_.size();
    const size_t piece = std::min(size, kMaxFrameBytes);
    held_.insert(held_.end(), data, data + piece);
    const size_t used = scan(held_.data(), held_.size(), false, onFrame);
    if (used >= old) {
      held_.clear();
      data += used - old;
      size -= used - old;
    } else {
      held_.erase(held_.begin(), held_.begin() + static_cast<std::ptrdiff_t>(used));
      data += piece;
      size -= piece;
    }
  }
}

void StreamDecoder::finish(const Callback& onFrame) {
  if (finished_) return;
  if (framing_ == Framing::Auto) probe(true);
  if (framing_ != Framing::Auto) {
    decideHeld(true, onFrame);
  } else {
    stats_.bytesSkipped += held_.size();
    decided_ += held_.size();
    held_.clear();
  }
  finished_ = true;
}

void StreamDecoder::decideHeld(bool final, const Callback& onFrame) {
  const size_t used = scan(held_.data(), held_.size(), final, onFrame);
  held_.erase(held_.begin(), held_.begin() + static_cast<std::ptrdiff_t>(used));
}

size_t StreamDecoder::scan(const uint8_t* data, size_t n, bool final, const Callback& onFrame) {
  size_t pos = 0;
  bool truncatedCounted = false;
  while (true) {
    const size_t m = findMagic(data, n, pos);
    if (m == kNone) {
      // The last 3 bytes may be the start of a magic that the next piece completes.
      const size_t keep = final ? 0 : std::min<size_t>(3, n - pos);
      stats_.bytesSkipped += n - keep - pos;
      pos = n - keep;
      break;
    }
    stats_.bytesSkipped += m - pos;
    pos = m;
    const FrameCheck check = checkFrame(framing_, data + m, n - m);
    if (check.status == FrameCheck::Ok) {
      const Verdict verdict = judge(data, n, m, check, final);
      if (verdict == Verdict::NeedMore) break;
      if (verdict == Verdict::Accept) {
        emit(data + m, check, decided_ + m, onFrame);
        pos = m + check.size;
        continue;
      }
      if (verdict == Verdict::Overlap) ++stats_.rejectedOverlap;
      else ++stats_.rejectedUnusedBits;
    } else if (check.status == FrameCheck::NeedMore) {
      if (!final) break;
      if (!truncatedCounted) ++stats_.truncatedFrames;
      truncatedCounted = true;
    } else if (check.status == FrameCheck::BadHeader) {
      ++stats_.badHeaders;
    } else {
      ++stats_.crcFailures;
    }
    // Resynchronise from the byte after the failed magic.
    ++stats_.bytesSkipped;
    pos = m + 1;
  }
  decided_ += pos;
  return pos;
}

bool StreamDecoder::isPacket(const FrameCheck& check) const {
  return informationPackets_ && (framing_ == Framing::Dissertation ||
                                 (check.page == kInformationPage && check.length == kInformationQuadlets));
}

bool StreamDecoder::hasUnusedBits(const uint8_t* frame, const FrameCheck& check) const {
  if (!isPacket(check)) return false;
  const uint8_t* q = frame + (framing_ == Framing::Dissertation ? 4 : 8);
  for (int i = 0; i < kFirstEncoderQuadlet + kJointChannels; ++i)
    if (loadBigEndian32(q + 4 * i) & ~usedBits(i)) return true;
  return false;
}

StreamDecoder::Verdict StreamDecoder::judge(const uint8_t* data, size_t n, size_t magic, const FrameCheck& check,
                                            bool final) const {
  if (hasUnusedBits(data + magic, check)) return Verdict::UnusedBits;
  // Another frame starting inside this one: its magic may run up to 3 bytes past this frame's end.
  const size_t end = magic + check.size;
  if (!final && n < end + 3) return Verdict::NeedMore;
  for (size_t j = findMagic(data, n, magic + 1); j != kNone && j < end; j = findMagic(data, n, j + 1)) {
    const FrameCheck inner = checkFrame(framing_, data + j, n - j);
    if (inner.status == FrameCheck::NeedMore && !final) return Verdict::NeedMore;
    if (inner.status == FrameCheck::Ok && !hasUnusedBits(data + j, inner)) return Verdict::Overlap;
  }
  return Verdict::Accept;
}

void StreamDecoder::emit(const uint8_t* frame, const FrameCheck& check, uint64_t offset, const Callback& onFrame) {
  const uint8_t* p = frame + (framing_ == Framing::Dissertation ? 4 : 8);
  payload_.resize(static_cast<size_t>(check.length));  // within the reserved 1023: no allocation
  for (int i = 0; i < check.length; ++i) payload_[i] = loadBigEndian32(p + 4 * i);
  const bool packet = isPacket(check);
  if (packet) packet_ = decodePacket(payload_.data());
  ++stats_.framesOk;
  stats_.packets += packet;
  stats_.bytesInFrames += check.size;
  if (!onFrame) return;
  const DecodedFrame f{framing_, offset, static_cast<uint32_t>(check.size), check.page,
                       std::span<const uint32_t>(payload_.data(), payload_.size()), packet ? &packet_ : nullptr};
  onFrame(f);
}

void StreamDecoder::probe(bool final) {
  const uint8_t* data = held_.data();
  const size_t n = held_.size();
  size_t pos = static_cast<size_t>(probeFrom_ - decided_);
  probeAgainAt_ = 0;
  while (true) {
    const size_t m = findMagic(data, n, pos);
    if (m == kNone) {
      pos = final ? n : std::max(pos, n - std::min<size_t>(3, n));
      break;
    }
    const LockResult r = tryLock(data, n, m, final);
    if (r == LockResult::Locked) return;
    if (r == LockResult::NeedMore) {
      // Look again once the bytes after this magic have doubled (at least 4 KiB more), so that
      // a long idle gap is not rescanned for every small piece.
      pos = m;
      probeAgainAt_ = decided_ + n + std::max<size_t>(4096, n - m);
      break;
    }
    pos = m + 1;
  }
  probeFrom_ = decided_ + pos;
  // Too much held without a decision: drop the oldest bytes (in large steps, so that the held
  // bytes are not moved for every piece).
  if (!final && pos > 2 * kAutoHoldBytes) {
    const size_t drop = pos - kAutoHoldBytes;
    held_.erase(held_.begin(), held_.begin() + static_cast<std::ptrdiff_t>(drop));
    decided_ += drop;
    stats_.bytesSkipped += drop;
  }
}

StreamDecoder::LockResult StreamDecoder::tryLock(const uint8_t* data, size_t n, size_t magic, bool final) {
  bool needMore = false;
  int passes = 0;
  Framing passing = Framing::Auto;
  for (Framing f : {Framing::Dissertation, Framing::Public}) {
    const FrameCheck first = checkFrame(f, data + magic, n - magic);
    if (first.status == FrameCheck::NeedMore) needMore = needMore || !final;
    if (first.status != FrameCheck::Ok) continue;
    // The next frame must follow at once or after idle (zero) bytes only.
    const size_t end = magic + first.size;
    size_t next = end;
    const size_t gapLimit = std::min(n, end + kMaxIdleGap + 1);
    while (next < gapLimit && data[next] == 0) ++next;
    if (next - end > kMaxIdleGap) continue;
    if (n - next < 4) {
      needMore = needMore || !final;
      continue;
    }
    if (loadBigEndian32(data + next) != kMagic) continue;
    const FrameCheck second = checkFrame(f, data + next, n - next);
    if (second.status == FrameCheck::NeedMore) needMore = needMore || !final;
    if (second.status != FrameCheck::Ok) continue;
    ++passes;
    passing = f;
  }
  if (needMore) return LockResult::NeedMore;
  if (passes != 1) return LockResult::NotHere;  // none, or (never seen in practice) both framings
  framing_ = passing;
  return LockResult::Locked;
}

}  // namespace viscera::robot::espm
