// Flash programming over the ESPM link against the simulated board: exact programming, retries
// under write failures, a stuck bit, a chip that was not erased, and the command layout.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "robot/espm/Flash.h"
#include "robot/espm/Framing.h"
#include "tests/support/ErrorOf.h"

using namespace viscera::robot::espm;
using viscera::test_support::errorOf;

namespace {

std::vector<uint8_t> randomImage(size_t size, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::vector<uint8_t> image(size);
  for (auto& b : image) b = static_cast<uint8_t>(rng());
  return image;
}

SimulatedBoardOptions smallBoard() {
  SimulatedBoardOptions o;
  o.flashBytes = 64 * 1024;
  o.erasePolls = 250;
  return o;
}

// Each exchange is a 134-byte command frame and a 134-byte answer.
constexpr double kExchangeSeconds = 2 * 134 * 8 / 20e6;

}  // namespace

TEST(EspmFlash, RandomImageProgramsExactly) {
  SimulatedEspmBoard board(smallBoard());
  const std::vector<uint8_t> image = randomImage(20001, 31);  // odd: the last word is padded with 0xFF
  const FlashReport report = FlashProgrammer(board).program(image);
  const std::vector<uint8_t> flash = board.flashContent();
  EXPECT_TRUE(std::equal(image.begin(), image.end(), flash.begin()));
  EXPECT_EQ(flash[image.size()], 0xFF);  // padding and the rest stay erased
  EXPECT_EQ(report.bytesWritten, image.size());
  EXPECT_EQ(report.retries, 0u);
  EXPECT_EQ(report.erasePolls, 250u);
  // enter + erase + 250 polls + 10001 words + leave.
  EXPECT_EQ(report.exchanges, 1u + 1 + 250 + 10001 + 1);
  EXPECT_EQ(board.commandsReceived(), report.exchanges);
  EXPECT_NEAR(report.lineTime, report.exchanges * kExchangeSeconds, 1e-12);
  EXPECT_FALSE(board.inFlashMode());  // it left flash mode at the end
}

TEST(EspmFlash, FivePercentWriteFailuresAreRetried) {
  SimulatedBoardOptions o = smallBoard();
  o.writeFailureProbability = 0.05;
  o.seed = 77;
  SimulatedEspmBoard board(o);
  const std::vector<uint8_t> image = randomImage(32768, 32);
  const FlashReport report = FlashProgrammer(board).program(image);
  const std::vector<uint8_t> flash = board.flashContent();
  EXPECT_TRUE(std::equal(image.begin(), image.end(), flash.begin()));
  // Every dropped write is noticed in the answer and costs exactly one retry.
  EXPECT_EQ(report.retries, board.programsDropped());
  // 16384 words, failures geometric with p = 0.05: retries ~ 16384 * 0.05 / 0.95 = 862, standard
  // deviation about sqrt(16384 * 0.05) / 0.95 = 30; the window is more than 6 of them each side.
  EXPECT_GT(report.retries, 660u);
  EXPECT_LT(report.retries, 1070u);
  EXPECT_EQ(report.exchanges, 1u + 1 + 250 + 16384 + report.retries + 1);
}

TEST(EspmFlash, StuckBitIsReportedAtItsAddress) {
  SimulatedBoardOptions o = smallBoard();
  o.stuckBits.push_back({0x1235, 3, false});  // always reads 0
  SimulatedEspmBoard board(o);
  std::vector<uint8_t> image = randomImage(8192, 33);
  image[0x1235] |= 0x08;  // the image needs a 1 there
  const std::string e = errorOf([&] { FlashProgrammer(board).program(image); });
  // The word at 0x1234 holds bytes 0x1234 (bits 15:8) and 0x1235 (bits 7:0): bit 3 of the latter.
  const std::string word = [&] {
    char text[8];
    std::snprintf(text, sizeof text, "0x%04X", image[0x1234] << 8 | image[0x1235]);
    return std::string(text);
  }();
  EXPECT_NE(e.find("the word at address 0x001234 does not verify after 16 writes: wrote " + word), std::string::npos) << e;
  EXPECT_NE(e.find("bits 0x0008 differ, first in byte 0x001235"), std::string::npos) << e;
}

TEST(EspmFlash, WritingWithoutErasingFailsVerification) {
  SimulatedEspmBoard board(smallBoard());
  // Left over from an earlier image: programming can only clear bits, so most words cannot take
  // the new value.
  const std::vector<uint8_t> old = randomImage(board.cells().size(), 34);
  std::copy(old.begin(), old.end(), board.cells().begin());
  const std::vector<uint8_t> image = randomImage(4096, 35);
  FlashOptions noErase;
  noErase.erase = false;
  noErase.maxWritesPerWord = 3;
  // The first word that needs a 1 where the old content has a 0.
  size_t expected = 0;
  while (((image[expected] & ~old[expected]) | (image[expected + 1] & ~old[expected + 1])) == 0) expected += 2;
  char address[16];
  std::snprintf(address, sizeof address, "0x%06zX", expected);
  const std::string e = errorOf([&] { FlashProgrammer(board, noErase).program(image); });
  EXPECT_NE(e.find(std::string("the word at address ") + address + " does not verify after 3 writes"), std::string::npos)
      << e;
  // With the erase, the same board programs it.
  FlashOptions withErase;
  FlashProgrammer(board, withErase).program(image);
  const std::vector<uint8_t> flash = board.flashContent();
  EXPECT_TRUE(std::equal(image.begin(), image.end(), flash.begin()));
}

TEST(EspmFlash, ImageLargerThanTheFlashIsRejected) {
  SimulatedBoardOptions o = smallBoard();
  o.flashBytes = 1024;
  SimulatedEspmBoard board(o);
  const std::string e = errorOf([&] { FlashProgrammer(board).program(randomImage(1030, 36)); });
  EXPECT_NE(e.find("rejected the word at address 0x000400"), std::string::npos) << e;
}

// The layout documented in Flash.h, frame by frame.
TEST(EspmFlash, CommandsAndAnswersFollowTheDocumentedLayout) {
  Packet info;
  info.instrumentId = 42;
  SimulatedBoardOptions o = smallBoard();
  o.erasePolls = 3;
  SimulatedEspmBoard board(o, info);
  StreamDecoder decoder(Framing::Dissertation, false);
  const auto send = [&](uint32_t q0, uint32_t q1 = 0, uint32_t q2 = 0) {
    Quadlets q{};
    q[0] = q0;
    q[1] = q1;
    q[2] = q2;
    std::vector<uint8_t> out, in;
    appendDissertationFrame(out, q);
    board.exchange(out, in);
    EXPECT_EQ(in.size(), kDissertationFrameBytes);
    std::vector<uint32_t> answer;
    const auto take = [&](const DecodedFrame& f) { answer.assign(f.payload.begin(), f.payload.end()); };
    decoder.reset();
    decoder.feed(in, take);
    decoder.finish(take);
    answer.resize(kInformationQuadlets);
    return answer;
  };
  // Normal mode: anything but 0xF1 is answered with the information packet.
  EXPECT_EQ(send(0x0020)[kInstrumentIdQuadlet], 42u);
  EXPECT_FALSE(board.inFlashMode());
  std::vector<uint32_t> a = send(0xF1, 0x10);
  EXPECT_TRUE(board.inFlashMode());
  EXPECT_EQ(a[0], 0xF1A50000u);
  EXPECT_EQ(a[1], 0x10u);
  EXPECT_EQ(a[2], 0xFFFFu);  // erased
  a = send(0x0040, 0x10, 0x1234);  // program
  EXPECT_EQ(a[2], 0x1234u);
  a = send(0x0040, 0x10, 0xFFFF);  // programming cannot set bits again
  EXPECT_EQ(a[2], 0x1234u);
  a = send(0x0040, 0x11, 0);  // odd address
  EXPECT_EQ(a[0], 0xF1A50000u | kFlashReplyRejected);
  a = send(0x0020);  // erase: the third command after it is the first answered ready
  EXPECT_EQ(a[0], 0xF1A50000u | kFlashReplyBusy);
  EXPECT_EQ(send(0x0000, 0x10)[0], 0xF1A50000u | kFlashReplyBusy);
  EXPECT_EQ(send(0x0040, 0x10, 0)[0], 0xF1A50000u | kFlashReplyBusy | kFlashReplyRejected);
  a = send(0x0000, 0x10);
  EXPECT_EQ(a[0], 0xF1A50000u);
  EXPECT_EQ(a[2], 0xFFFFu);
  EXPECT_EQ(send(0x00F0)[kInstrumentIdQuadlet], 42u);
  EXPECT_FALSE(board.inFlashMode());
}
