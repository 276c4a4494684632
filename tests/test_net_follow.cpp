// Cascades that follow the viewers (protocol version 9, PROTOCOL.md "Cascades that follow the
// viewers") against a real server and client over loopback: the server moves its cascades to
// the viewer, the client's copy moves with them, and once the field froze the client holds
// exactly the server's field in the server's places; an older client is refused with the
// reason.
#include <gtest/gtest.h>

#include "common/field_scroll.h"
#include "test_net_support.h"

namespace pc::nettest {
namespace {

TEST(NetFollow, TheClientsCopyMovesWithTheCascadesThatFollowItsViewer) {
  TestServer server(/*freezeAt=*/4.0, {}, 0, /*followViewers=*/true);
  std::vector<gpu::CascadeDesc> start;
  {
    auto lock = server.hub().lock();
    start = server.hub().publisher().sessionInfo().cascades;
  }
  ASSERT_FALSE(start.empty());
  // A viewer 1.2 of the coarsest spacings off the cascades' middle, on x and z: every cascade
  // has to move, and stays within the room (probes outside see nothing but the sky, whose
  // depth-only changes the tracers do not count as changes).
  const gpu::CascadeDesc& coarsest = start.back();
  const glm::vec3 middle =
      coarsest.origin + glm::vec3(coarsest.counts - 1) * (0.5f * coarsest.spacing);
  const glm::vec3 viewer = middle + glm::vec3(1.2f, 0.0f, -1.2f) * coarsest.spacing;

  client::FieldMirror mirror;
  client::NetClient client(mirror, secureClientOptions(server, "follower"));
  client.setViewer(viewer, glm::quat(1, 0, 0, 0));
  client.start();
  const bool converged = waitFor(
      [&] { return server.frozen() && mirrorDifference(mirror, server.field()) == 0; }, 60.0);
  const FieldLoopStats stats = server.loop().stats();
  std::printf("follow: %llu moves, %llu probes re-traced, converged %d\n",
              (unsigned long long)stats.scrolls, (unsigned long long)stats.scrolledProbes,
              int(converged));
  ASSERT_TRUE(converged);
  EXPECT_GE(stats.scrolls, std::uint64_t(start.size()));
  const Field& field = server.field();
  const std::optional<gpu::FieldDesc> held = mirror.desc();
  ASSERT_TRUE(held.has_value());
  for (int k = 0; k < field.cascadeCount(); ++k) {
    const gpu::CascadeDesc& c = field.cascade(k);
    EXPECT_NE(c.origin, start[std::size_t(k)].origin) << "cascade " << k << " did not move";
    // The viewer now lies within a spacing of the cascade's middle on each axis it moved on.
    EXPECT_EQ(followShift(c, viewer), glm::ivec3(0)) << "cascade " << k;
    EXPECT_EQ(held->cascades[k].origin, c.origin) << "cascade " << k;
    EXPECT_EQ(held->cascades[k].scroll, c.scroll) << "cascade " << k;
  }
  // Moving never reset the client's copy: it moved in place.
  EXPECT_EQ(client.stats().layoutResets, 1u);
}

TEST(NetFollow, AClientTooOldForMovingCascadesIsToldWhy) {
  TestServer server(/*freezeAt=*/0.5, {}, 0, /*followViewers=*/true);
  RawPeer peer(server.port());
  peer.send(helloFrame(kToken, false, kFirstMovingCascadesVersion - 1));
  const auto frame = peer.readFrame(10.0);
  ASSERT_TRUE(frame.has_value());
  auto message = decodeMessage(*frame);
  ASSERT_TRUE(message.ok()) << message.error().message;
  const auto* reject = std::get_if<RejectMsg>(&*message);
  ASSERT_NE(reject, nullptr) << "not a Reject: " << sessionMessageName(*message);
  EXPECT_NE(reject->reason.find("follow the viewers"), std::string::npos) << reject->reason;
  // A current client of the same server is served.
  RawPeer current(server.port());
  current.send(helloFrame(kToken, false, kProtocolVersion));
  const auto welcome = current.readFrame(10.0);
  ASSERT_TRUE(welcome.has_value());
  auto answer = decodeMessage(*welcome);
  ASSERT_TRUE(answer.ok());
  EXPECT_TRUE(std::holds_alternative<WelcomeMsg>(*answer)) << sessionMessageName(*answer);
}

}  // namespace
}  // namespace pc::nettest
