// Acks sent as datagrams (protocol/uplink_datagram.h, PROTOCOL.md "Acks over UDP"): the format
// both ends speak, what the server's opener refuses and why, and the receiver's repetition of
// what earlier acks said, which makes a lost ack cost a delay only.
#include <gtest/gtest.h>

#include <random>
#include <variant>

#include "protocol/field_publisher.h"
#include "protocol/net_framing.h"
#include "protocol/session_messages.h"
#include "protocol/stream_receiver.h"
#include "protocol/uplink_datagram.h"
#include "test_protocol_support.h"

namespace pc {
namespace {

using Bytes = std::vector<std::uint8_t>;

DatagramKey keyOf(std::uint8_t b) {
  DatagramKey k;
  k.fill(b);
  return k;
}

Bytes ackFrame() {
  AckMsg ack;
  ack.full = true;
  ack.ranges.push_back(AckRange{0, 0, 3, 42});
  return encodeMessage(ack);
}

TEST(UplinkDatagram, OpensWhatTheSessionsClientSealedAndDropsTheRestByCause) {
  const Bytes frame = ackFrame();
  UplinkWriter writer(keyOf(1), 9);
  UplinkOpener opener(keyOf(1), 9);
  const Bytes first = writer.wrap(frame).value();
  EXPECT_EQ(first.size(), frame.size() + kSealOverheadBytes);
  EXPECT_EQ(peekUplink(first)->sessionId, 9u);
  EXPECT_TRUE(peekUplink(first)->sealed);
  UplinkDrop cause = UplinkDrop::Malformed;
  auto opened = opener.open(first, cause);
  ASSERT_TRUE(opened.ok()) << opened.error().message;
  EXPECT_EQ(Bytes(opened->begin(), opened->end()), frame);

  auto dropCause = [&](UplinkOpener& o, const Bytes& d) {
    UplinkDrop c = UplinkDrop(255);
    EXPECT_FALSE(o.open(d, c).ok());
    return c;
  };
  EXPECT_EQ(dropCause(opener, first), UplinkDrop::Replayed);
  UplinkWriter forger(keyOf(2), 9);
  EXPECT_EQ(dropCause(opener, forger.wrap(frame).value()), UplinkDrop::Forged);
  UplinkWriter other(keyOf(1), 10);
  EXPECT_EQ(dropCause(opener, other.wrap(frame).value()), UplinkDrop::UnknownSession);
  UplinkWriter plain(std::nullopt, 9);
  EXPECT_EQ(dropCause(opener, plain.wrap(frame).value()), UplinkDrop::WrongMode);
  EXPECT_EQ(dropCause(opener, Bytes(first.begin(), first.begin() + 12)), UplinkDrop::Malformed);
  EXPECT_EQ(dropCause(opener, Bytes(kMaxUplinkDatagramBytes + 1, 'P')), UplinkDrop::Oversized);
  // Authentic, but not one whole frame: the window counts it, the server takes nothing.
  EXPECT_EQ(dropCause(opener, writer.wrap(Bytes{1, 2, 3}).value()), UplinkDrop::NotAFrame);
  // Reordered datagrams open, each once.
  const Bytes a = writer.wrap(frame).value(), b = writer.wrap(frame).value();
  EXPECT_TRUE(opener.open(b, cause).ok());
  EXPECT_TRUE(opener.open(a, cause).ok());
  EXPECT_EQ(dropCause(opener, a), UplinkDrop::Replayed);
  EXPECT_FALSE(writer.wrap(Bytes(kMaxUplinkFrameBytes + 1, 0)).ok());

  // The plain form (sessions without TLS): the same header, the frame in clear, no tag.
  UplinkOpener plainOpener(std::nullopt, 9);
  const Bytes p = plain.wrap(frame).value();
  EXPECT_EQ(std::string(p.begin(), p.begin() + 4), "PCSP");
  EXPECT_EQ(p.size(), frame.size() + kUplinkHeaderBytes);
  ASSERT_TRUE(plainOpener.open(p, cause).ok());
  EXPECT_EQ(dropCause(plainOpener, p), UplinkDrop::Replayed);
  EXPECT_EQ(dropCause(plainOpener, first), UplinkDrop::WrongMode);
  Bytes cut = plain.wrap(frame).value();
  cut.pop_back();
  EXPECT_EQ(dropCause(plainOpener, cut), UplinkDrop::NotAFrame);
  EXPECT_EQ(opener.opened(), 3u);
  EXPECT_EQ(plainOpener.opened(), 1u);
}

// Acks of one brick update and its datagram's arrival, polled every ack interval.
std::vector<AckMsg> acksAfterOneUpdate(int repeats) {
  Field server = test::makeSyntheticLayout();
  std::mt19937 rng(3);
  test::evolveField(server, rng, 1.0f, 0.0f);
  FieldPublisher pub(server);
  EXPECT_TRUE(pub.publish(server, 0.0).ok());
  ReceiverOptions options;
  options.ackRepeats = repeats;
  auto rx = StreamReceiver::create(pub.sessionInfo(), 7, options);
  EXPECT_TRUE(rx.ok());
  (void)rx->poll(0.0);  // the first full ack
  auto enc = pub.encoded(0, 0, server.brickVersions[0][0], 0);
  EXPECT_TRUE(enc);
  for (std::uint16_t i = 0; i < fragmentCount(enc->header.totalSize); ++i) {
    const std::size_t b = std::size_t(i) * kFragmentBytes;
    std::vector<FragmentRef> f{
        {enc->header, i,
         std::span(enc->payload).subspan(b, std::min(kFragmentBytes, enc->payload.size() - b))}};
    EXPECT_TRUE(rx->onDatagram(encodeDatagram(7, i, 1, f), 0.05).ok());
  }
  std::vector<AckMsg> acks;
  for (double t = 0.1; t < 0.3; t += 0.03) {
    for (const Bytes& m : rx->poll(t)) {
      auto msg = decodeMessage(m);
      EXPECT_TRUE(msg.ok());
      if (auto* ack = std::get_if<AckMsg>(&*msg)) acks.push_back(*ack);
    }
  }
  return acks;
}

TEST(UplinkDatagram, AcksRepeatTheChangesAndArrivalsOfTheTwoBeforeThem) {
  const std::vector<AckMsg> once = acksAfterOneUpdate(0);
  ASSERT_EQ(once.size(), 1u);  // over the stream nothing is lost: one ack says it
  const std::size_t arrivals = once[0].arrivals.size();
  EXPECT_GE(arrivals, 1u);

  const std::vector<AckMsg> repeated = acksAfterOneUpdate(2);
  ASSERT_EQ(repeated.size(), 3u);  // and two more as datagrams
  for (const AckMsg& ack : repeated) {
    EXPECT_FALSE(ack.full);
    ASSERT_EQ(ack.ranges.size(), 1u);
    EXPECT_EQ(ack.ranges[0].cascade, 0);
    EXPECT_EQ(ack.ranges[0].firstBrick, 0u);
    EXPECT_EQ(ack.ranges[0].version, once[0].ranges[0].version);
    // A lost ack's arrivals come again: the sender never reads their datagrams as lost.
    ASSERT_EQ(ack.arrivals.size(), arrivals);
    EXPECT_EQ(ack.arrivals[0].sequence, once[0].arrivals[0].sequence);
    EXPECT_EQ(ack.arrivals[0].arrivalMicros, once[0].arrivals[0].arrivalMicros);
  }
}

}  // namespace
}  // namespace pc
