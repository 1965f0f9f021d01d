// The edge simulator of robot/encoder/Quadrature: edges per revolution, their order in both
// directions, reversals, edge times against the closed form of a constant-speed motion, and the
// quantisation to FPGA clock ticks.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <stdexcept>
#include <vector>

#include "robot/encoder/EncoderFpga.h"
#include "robot/encoder/Motion.h"
#include "robot/encoder/Quadrature.h"

using namespace viscera::robot::encoder;

namespace {

constexpr double kPi = std::numbers::pi;

JointMotion constantSpeed(double angle0, double speed) {
  return {[=](double t) { return angle0 + speed * t; }, [=](double) { return speed; }};
}

EncoderSpec encoder(double lines, double dutyA = 0.5, double dutyB = 0.5, double phase = 90) {
  EncoderSpec s;
  s.lines = lines;
  s.dutyA = dutyA;
  s.dutyB = dutyB;
  s.phaseB = phase;
  return s;
}

// Index of an edge type in the forward order A rise, B rise, A fall, B fall.
int forwardIndex(Edge e) {
  switch (e) {
    case Edge::ARise: return 0;
    case Edge::BRise: return 1;
    case Edge::AFall: return 2;
    case Edge::BFall: return 3;
  }
  return -1;
}

}  // namespace

TEST(Quadrature, FourEdgesPerLineInOneRevolution) {
  // One revolution from an angle that is not on an edge: every edge position is crossed once.
  for (const EncoderSpec& spec : {encoder(16), encoder(600), encoder(16, 0.4, 0.4, 90), encoder(16, 0.5, 0.5, 70)}) {
    const QuadratureEncoder enc(spec);
    const double speed = 2 * kPi;  // one revolution per second
    const auto events = enc.simulate(constantSpeed(0.01, speed), 0, 1, 1e-3);
    EXPECT_EQ(events.size(), static_cast<size_t>(4 * spec.lines)) << spec.lines << " lines";
    EXPECT_EQ(enc.count(0.01 + 2 * kPi) - enc.count(0.01), static_cast<int64_t>(4 * spec.lines));
  }
}

TEST(Quadrature, ForwardOrderIsARiseBRiseAFallBFallAndBackwardTheReverse) {
  const QuadratureEncoder enc(encoder(16, 0.45, 0.55, 80));
  const auto forward = enc.simulate(constantSpeed(0.01, 3.0), 0, 1, 1e-3);
  ASSERT_GT(forward.size(), 8u);
  for (size_t i = 1; i < forward.size(); ++i) {
    EXPECT_TRUE(forward[i].forward);
    EXPECT_EQ(forwardIndex(forward[i].type), (forwardIndex(forward[i - 1].type) + 1) % 4) << "edge " << i;
  }
  // Backward: B rise, A rise, B fall, A fall, repeating.
  const Edge backwardOrder[4] = {Edge::BRise, Edge::ARise, Edge::BFall, Edge::AFall};
  const auto backward = enc.simulate(constantSpeed(0.01, -3.0), 0, 1, 1e-3);
  ASSERT_GT(backward.size(), 8u);
  int start = 0;
  while (backwardOrder[start] != backward[0].type) ++start;
  for (size_t i = 0; i < backward.size(); ++i) {
    EXPECT_FALSE(backward[i].forward);
    EXPECT_EQ(backward[i].type, backwardOrder[(start + i) % 4]) << "edge " << i;
  }
}

TEST(Quadrature, EdgeTimesMatchTheClosedFormAndAreQuantisedToTicks) {
  // theta = theta0 + w t crosses cycle position e at t = (e / (lines / 2 pi) - theta0) / w.
  const EncoderSpec spec = encoder(16, 0.45, 0.55, 80);
  const QuadratureEncoder enc(spec);
  const double theta0 = 0.01, w = 5.0;
  const auto events = enc.simulate(constantSpeed(theta0, w), 0, 1, 1e-3);
  const double edgeAt[4] = {0, spec.phaseB / 360, spec.dutyA, spec.phaseB / 360 + spec.dutyB};
  const double cpr = spec.lines / (2 * kPi);
  double n = std::floor(theta0 * cpr);
  int k = 0;
  while (n + edgeAt[k] <= theta0 * cpr) {
    if (++k == 4) k = 0, n += 1;
  }
  for (const EdgeEvent& ev : events) {
    const double exact = ((n + edgeAt[k]) / cpr - theta0) / w;
    // The root finder stops at 1e-12 s; the angle's rounding adds about 1e-16 rad / 5 rad/s.
    EXPECT_NEAR(ev.time, exact, 2e-12);
    EXPECT_EQ(ev.tick, static_cast<int64_t>(std::ceil(exact * spec.clockHz)));
    // The tick is the first clock edge at or after the crossing.
    EXPECT_LE(static_cast<double>(ev.tick - 1) / spec.clockHz, ev.time);
    EXPECT_GE(static_cast<double>(ev.tick) / spec.clockHz, ev.time);
    if (++k == 4) k = 0, n += 1;
  }
}

TEST(Quadrature, AReversalCrossesTheSameEdgesBackInReverseWithFlippedTransitions) {
  // Out to 2.3 rad and back to 0: theta = 2.3 sin(pi t), t in [0, 1], reversal at t = 0.5.
  const QuadratureEncoder enc(encoder(16, 0.45, 0.55, 80));
  const JointMotion m{[](double t) { return 0.001 + 2.3 * std::sin(kPi * t); }, [](double t) { return 2.3 * kPi * std::cos(kPi * t); }};
  const auto events = enc.simulate(m, 0, 1, 1e-2);
  ASSERT_EQ(events.size() % 2, 0u);
  const size_t half = events.size() / 2;
  ASSERT_GT(half, 10u);
  for (size_t i = 0; i < half; ++i) {
    const EdgeEvent& out = events[i];
    const EdgeEvent& back = events[events.size() - 1 - i];
    EXPECT_TRUE(out.forward);
    EXPECT_FALSE(back.forward);
    EXPECT_LT(out.time, 0.5);
    EXPECT_GT(back.time, 0.5);
    // Same position crossed the other way: same channel, other transition; symmetric in time.
    EXPECT_EQ(back.type, edgeCrossed(forwardIndex(out.type), false));
    EXPECT_NEAR(back.time, 1 - out.time, 1e-9);
  }
  // The decoder fed with these edges ends where it started.
  const int64_t ticks[] = {events.back().tick};
  const auto reads = readAt(events, enc.levels(m.angle(0)), enc.count(m.angle(0)), ticks);
  EXPECT_EQ(reads[0].position, enc.count(m.angle(0)));
  EXPECT_EQ(reads[0].position, enc.count(m.angle(1)));
}

TEST(Quadrature, DecoderCountFollowsTheAngleThroughReversals) {
  const QuadratureEncoder enc(encoder(16, 0.5, 0.47, 70));
  const JointMotion m = sinusoidMotion({{3.0, 0.7, 0.3}, {0.8, 2.9, 1.1}});
  const auto events = enc.simulate(m, 0, 3, 1e-3);
  std::vector<int64_t> ticks;
  for (int k = 1; k <= 30; ++k) ticks.push_back(static_cast<int64_t>(std::llround(0.1 * k * kFpgaClockHz)));
  const auto reads = readAt(events, enc.levels(m.angle(0)), enc.count(m.angle(0)), ticks);
  for (size_t k = 0; k < ticks.size(); ++k) {
    const double t = static_cast<double>(ticks[k]) / kFpgaClockHz;
    EXPECT_EQ(reads[k].position, enc.count(m.angle(t))) << "t = " << t;
  }
  // The channel levels the FPGA tracks end as the channel pattern at the final angle.
  EncoderFpga fpga(enc.levels(m.angle(0)));
  for (const EdgeEvent& e : events) {
    ChannelLevels l = fpga.levels();
    (static_cast<uint8_t>(e.type) & 0xA ? l.a : l.b) ^= true;
    fpga.sample(e.tick, l);
  }
  EXPECT_EQ(fpga.levels().a, enc.levels(m.angle(3)).a);
  EXPECT_EQ(fpga.levels().b, enc.levels(m.angle(3)).b);
}

TEST(Quadrature, TwoCrossingsOfOneEdgeWithinATickAreInvisible) {
  // The angle rises to just past A's rising edge at cycle 1 and falls back: theta = e + d - b (t - tm)^2
  // crosses e at tm -+ sqrt(d / b). With that half-width 3 ns and tm in the middle of a tick (20.3 ns
  // long), both crossings fall into one tick; with 30 ns they do not.
  const EncoderSpec spec = encoder(16);
  const QuadratureEncoder enc(spec);
  const double e = 2 * kPi / spec.lines;  // angle of A's rise in cycle 1
  const double b = 1e3, tm = (1000 + 0.5) / spec.clockHz;
  auto parabola = [&](double halfWidth) {
    const double d = b * halfWidth * halfWidth;
    return JointMotion{[=](double t) { return e + d - b * (t - tm) * (t - tm); }, [=](double t) { return -2 * b * (t - tm); }};
  };
  EXPECT_TRUE(enc.simulate(parabola(3e-9), 0, 2 * tm, 1e-6).empty());
  const auto visible = enc.simulate(parabola(30e-9), 0, 2 * tm, 1e-6);
  ASSERT_EQ(visible.size(), 2u);
  EXPECT_EQ(visible[0].type, Edge::ARise);
  EXPECT_EQ(visible[1].type, Edge::AFall);
  EXPECT_LT(visible[0].tick, visible[1].tick);
}

TEST(Quadrature, LevelsAndCountAtKnownAngles) {
  // 16 lines, A high [0, 0.5), B high [0.25, 0.75) of a cycle of 2 pi / 16 rad.
  const QuadratureEncoder enc(encoder(16));
  const double cycle = 2 * kPi / 16;
  const struct {
    double fraction;
    bool a, b;
    int64_t count;
  } cases[] = {{0.1, true, false, 0}, {0.3, true, true, 1}, {0.6, false, true, 2}, {0.8, false, false, 3}, {1.1, true, false, 4}, {-0.1, false, false, -1}};
  for (const auto& c : cases) {
    const ChannelLevels l = enc.levels(c.fraction * cycle);
    EXPECT_EQ(l.a, c.a) << c.fraction;
    EXPECT_EQ(l.b, c.b) << c.fraction;
    EXPECT_EQ(enc.count(c.fraction * cycle), c.count) << c.fraction;
  }
}

TEST(Quadrature, RejectsChannelsThatAreNotInQuadrature) {
  EXPECT_THROW(QuadratureEncoder(encoder(0)), std::invalid_argument);
  EXPECT_THROW(QuadratureEncoder(encoder(16, 1.0)), std::invalid_argument);
  // B must rise while A is high: a 200 degree phase with A high half the cycle is not quadrature.
  EXPECT_THROW(QuadratureEncoder(encoder(16, 0.5, 0.5, 200)), std::invalid_argument);
  // B must fall after A falls.
  EXPECT_THROW(QuadratureEncoder(encoder(16, 0.6, 0.3, 90)), std::invalid_argument);
  try {
    validate(encoder(16, 0.5, 0.5, 200));
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()).rfind("phaseB: ", 0), 0u) << e.what();
  }
}
