// Runtime edits: the checks on every field of an edit, the messages, the probe scheduler's
// priority for the probes near an edit, and edits over real sessions (an editor's applied and
// seen by viewers, a viewer's refused, hostile values refused with the session intact).
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "common/emissive_lights.h"
#include "common/scene_edits.h"
#include "protocol/client_session.h"
#include "server/probe_scheduler.h"
#include "test_net_support.h"

namespace pc {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr float kInf = std::numeric_limits<float>::infinity();

SceneEdit lightEdit(std::uint32_t light, float intensity) {
  SceneEdit e;
  e.op = EditOp::SetLight;
  e.target = light;
  e.fields = kEditIntensity;
  e.intensity = intensity;
  return e;
}

SceneEdit emissionEdit(std::uint32_t material, float factor) {
  SceneEdit e;
  e.op = EditOp::SetEmission;
  e.target = material;
  e.emission = factor;
  return e;
}

SceneEdit addLightEdit(glm::vec3 position, float range) {
  SceneEdit e;
  e.op = EditOp::AddLight;
  e.fields = kEditPosition | kEditRange;
  e.position = position;
  e.range = range;
  return e;
}

// The built-in room with its white material glowing: a scene with an emitter.
Scene glowingScene() {
  Scene s = builtinScene();
  s.materials.push_back({.name = "lamp", .emissive = {4.0f, 4.0f, 4.0f}});
  s.meshes[3].material = 3;               // both blocks glow
  s.emissiveMode = EmissiveMode::Lights;  // sampled as lights, whatever their area
  return s;
}

TEST(SceneEdits, AppliesEachKindOnTopOfTheAnimation) {
  const Scene scene = glowingScene();
  SceneEdits edits(scene);
  EXPECT_EQ(edits.evaluate(1.0).editVersion, 0u);

  SceneEdit light = lightEdit(0, 5.0f);
  light.fields |= kEditColor | kEditPosition;
  light.color = {1.0f, 0.5f, 0.2f};
  light.position = {0.1f, 1.2f, 0.3f};
  ASSERT_TRUE(edits.apply(light, 1.0).ok());
  SceneEdit add = addLightEdit({0.0f, 1.0f, 0.0f}, 1.5f);
  add.fields |= kEditIntensity;
  add.intensity = 2.0f;
  auto added = edits.apply(add, 1.0);
  ASSERT_TRUE(added.ok());
  EXPECT_EQ(added->target, 1u);  // after the scene's one light
  SceneEdit move;
  move.op = EditOp::MoveInstance;
  move.target = 4;  // the short block, animated
  move.transform = glm::translate(glm::mat4(1.0f), {0.2f, 0.3f, 0.1f});
  ASSERT_TRUE(edits.apply(move, 1.0).ok());
  ASSERT_TRUE(edits.apply(emissionEdit(3, 0.0f), 1.0).ok());
  SceneEdit remove;
  remove.op = EditOp::RemoveLight;
  remove.target = 1;
  ASSERT_TRUE(edits.apply(remove, 1.0).ok());
  EXPECT_EQ(edits.version(), 5u);

  const SceneState s = edits.evaluate(2.0);  // later: the animation would have moved both
  EXPECT_EQ(s.editVersion, 5u);
  ASSERT_EQ(s.lights.size(), 2u);
  EXPECT_EQ(s.addedLights, 1u);
  EXPECT_EQ(s.lights[0].intensity, 5.0f);
  EXPECT_EQ(s.lights[0].color, glm::vec3(1.0f, 0.5f, 0.2f));
  EXPECT_EQ(s.lights[0].position, glm::vec3(0.1f, 1.2f, 0.3f));
  EXPECT_EQ(s.lights[1].type, LightType::Point);
  EXPECT_EQ(s.lights[1].intensity, 0.0f);  // removed, kept in place
  EXPECT_EQ(s.instanceTransforms[4], move.transform);
  EXPECT_EQ(s.emissionScaleOf(3), 0.0f);
  EXPECT_EQ(s.emissionScaleOf(0), 1.0f);
  // The tracers' emitter list follows the factor: switched off, nothing is sampled.
  EXPECT_FALSE(EmissiveLights::build(scene, evaluateScene(scene, 2.0)).empty());
  EXPECT_TRUE(EmissiveLights::build(scene, s).empty());
}

TEST(SceneEdits, RefusesHostileValuesAndChangesNothing) {
  const Scene scene = glowingScene();
  SceneEdits edits(scene);
  SceneEdit huge = lightEdit(0, 1.0f);
  huge.fields = kEditPosition;
  huge.position = {1e9f, 0.0f, 0.0f};
  SceneEdit nanColor = lightEdit(0, 1.0f);
  nanColor.fields = kEditColor;
  nanColor.color = {kNaN, 1.0f, 1.0f};
  SceneEdit zeroDirection = lightEdit(0, 1.0f);
  zeroDirection.fields = kEditDirection;
  zeroDirection.direction = glm::vec3(0.0f);
  SceneEdit noFields = lightEdit(0, 1.0f);
  noFields.fields = 0;
  SceneEdit unknownFields = lightEdit(0, 1.0f);
  unknownFields.fields = 1u << 20;
  SceneEdit staticInstance;
  staticInstance.op = EditOp::MoveInstance;
  staticInstance.target = 3;  // the tall block: static
  SceneEdit badMatrix;
  badMatrix.op = EditOp::MoveInstance;
  badMatrix.target = 4;
  badMatrix.transform[2][2] = kInf;
  SceneEdit singular = badMatrix;
  singular.transform = glm::mat4(0.0f);
  singular.transform[3][3] = 1.0f;
  SceneEdit mirrored = badMatrix;
  mirrored.transform = glm::scale(glm::mat4(1.0f), {-1.0f, 1.0f, 1.0f});
  const SceneEdit dark = emissionEdit(1, 1.0f);  // red: emits nothing
  const SceneEdit tooBright = emissionEdit(3, 1e9f);
  SceneEdit addWithoutPosition;
  addWithoutPosition.op = EditOp::AddLight;
  addWithoutPosition.fields = kEditIntensity;
  const std::vector<std::pair<SceneEdit, std::string>> cases = {
      {lightEdit(7, 1.0f), "light 7 does not exist"},
      {lightEdit(0, kNaN), "intensity is not finite"},
      {lightEdit(0, kInf), "intensity is not finite"},
      {lightEdit(0, -1.0f), "outside"},
      {lightEdit(0, 1e30f), "outside"},
      {huge, "position"},
      {nanColor, "colour"},
      {zeroDirection, "direction has no length"},
      {noFields, "name at least one"},
      {unknownFields, "name at least one"},
      {staticInstance, "static"},
      {badMatrix, "transform element"},
      {singular, "determinant"},
      {mirrored, "mirrors"},
      {dark, "emits nothing"},
      {tooBright, "emission"},
      {addWithoutPosition, "needs a position"},
  };
  for (const auto& [edit, why] : cases) {
    auto applied = edits.apply(edit, 0.5);
    ASSERT_FALSE(applied.ok()) << why;
    EXPECT_NE(applied.error().message.find(why), std::string::npos)
        << applied.error().message << " (expected: " << why << ")";
  }
  EXPECT_EQ(edits.version(), 0u);
  const SceneState untouched = edits.evaluate(0.5), animated = evaluateScene(scene, 0.5);
  EXPECT_EQ(untouched.lights[0].position, animated.lights[0].position);
  EXPECT_EQ(untouched.lights[0].intensity, animated.lights[0].intensity);
  EXPECT_EQ(untouched.instanceTransforms, animated.instanceTransforms);

  // Added lights are bounded, and a removed light takes no more edits.
  const SceneEdit add = addLightEdit({0.0f, 1.0f, 0.0f}, 0.0f);
  for (std::uint32_t i = 0; i < kMaxAddedLights; ++i) ASSERT_TRUE(edits.apply(add, 0.5).ok());
  EXPECT_FALSE(edits.apply(add, 0.5).ok());
  SceneEdit remove;
  remove.op = EditOp::RemoveLight;
  remove.target = 0;
  ASSERT_TRUE(edits.apply(remove, 0.5).ok());
  EXPECT_FALSE(edits.apply(lightEdit(0, 2.0f), 0.5).ok());
}

TEST(EditMessages, RoundTripAndCarryAddedLightsToTheClientsState) {
  EditMsg edit;
  edit.editId = 42;
  edit.edit = lightEdit(0, 5.0f);
  edit.edit.fields |= kEditColor;
  edit.edit.color = {1.0f, 0.5f, 0.2f};
  auto decoded = decodeMessage(encodeMessage(edit));
  ASSERT_TRUE(decoded.ok());
  const auto& e = std::get<EditMsg>(*decoded);
  EXPECT_EQ(e.editId, 42u);
  EXPECT_EQ(e.edit.op, EditOp::SetLight);
  EXPECT_EQ(e.edit.fields, kEditIntensity | kEditColor);
  EXPECT_EQ(e.edit.color, glm::vec3(1.0f, 0.5f, 0.2f));
  // Hostile values pass decoding (SceneEdits names them in the EditResult); an unknown
  // operation does not.
  edit.edit.intensity = kNaN;
  ASSERT_TRUE(decodeMessage(encodeMessage(edit)).ok());
  edit.edit.op = EditOp(9);
  EXPECT_FALSE(decodeMessage(encodeMessage(edit)).ok());

  auto result = decodeMessage(encodeMessage(EditResultMsg{7, false, std::string(5000, 'x'), 0, 3}));
  ASSERT_TRUE(result.ok());
  EXPECT_EQ(std::get<EditResultMsg>(*result).reason.size(), kMaxEditReasonBytes);

  // A state with an added light and an emission factor reaches a client's own evaluation.
  const Scene scene = glowingScene();
  SceneEdits edits(scene);
  const SceneEdit add = addLightEdit({0.2f, 1.0f, 0.0f}, 2.0f);
  ASSERT_TRUE(edits.apply(add, 0.0).ok());
  ASSERT_TRUE(edits.apply(emissionEdit(3, 0.25f), 0.0).ok());
  auto wire = decodeMessage(encodeMessage(sceneStateMessage(edits.evaluate(0.0))));
  ASSERT_TRUE(wire.ok());
  const auto& msg = std::get<SceneStateMsg>(*wire);
  EXPECT_EQ(msg.editVersion, 2u);
  SceneState client = evaluateScene(scene, 3.0);
  ASSERT_TRUE(applySceneState(msg, client).ok());
  ASSERT_EQ(client.lights.size(), 2u);
  EXPECT_EQ(client.lights[1].position, add.position);
  EXPECT_EQ(client.lights[1].range, 2.0f);
  EXPECT_EQ(client.emissionScaleOf(3), 0.25f);
  EXPECT_EQ(client.editVersion, 2u);
  // A light the scene does not have, not marked as added, is another scene's state.
  SceneStateMsg forged = msg;
  forged.lights[1].added = false;
  SceneState other = evaluateScene(scene, 3.0);
  EXPECT_FALSE(applySceneState(forged, other).ok());
}

TEST(EditMessages, ClientSendsEditsOnlyToServersThatTakeThem) {
  const Field field = Field::create(defaultVolumes(builtinScene()), FieldSettings{});
  for (const std::uint32_t version : {kEditsVersion - 1, kEditsVersion}) {
    ClientSession session(ClientSessionOptions{});
    const EditMsg edit{9, lightEdit(0, 2.0f)};
    EXPECT_FALSE(session.sendEdit(edit).ok());  // no session yet
    session.connecting(0.0);
    (void)session.connected(0.0, 0);
    std::vector<std::uint8_t> bytes = encodeMessage(WelcomeMsg{version, 1});
    const std::vector<std::uint8_t> info = encodeMessage(sessionInfoFor(field));
    bytes.insert(bytes.end(), info.begin(), info.end());
    ASSERT_TRUE(session.onStreamBytes(bytes, 0.0).ok());
    ASSERT_TRUE(session.streaming());
    const Status sent = session.sendEdit(edit);
    auto frames = session.poll(0.01);
    ASSERT_TRUE(frames.ok());
    std::size_t edits = 0;
    for (const auto& f : *frames) {
      auto m = decodeMessage(f);
      edits += m && std::holds_alternative<EditMsg>(*m) ? 1 : 0;
    }
    if (version < kEditsVersion) {
      ASSERT_FALSE(sent.ok());
      EXPECT_NE(sent.error().message.find("takes no edits"), std::string::npos);
      EXPECT_EQ(edits, 0u);
    } else {
      EXPECT_TRUE(sent.ok());
      EXPECT_EQ(edits, 1u);
    }
  }
}

TEST(EditScheduling, ProbesNearAnEditComeFirst) {
  const Scene scene = builtinScene();
  Field field = Field::create(defaultVolumes(scene), FieldSettings{});
  SchedulerOptions options;
  options.budget = 24;
  ProbeScheduler scheduler(options);
  // Every probe once, so that staleness alone would rank them evenly.
  ProbeScheduler everyone;
  (void)everyone.plan(field, 1);
  for (std::uint64_t t = 1; t <= 3; ++t) (void)scheduler.plan(field, t);

  const EditRegion region{{0.8f, 0.2f, 0.8f}, 0.6f};  // one corner of the room
  scheduler.prioritize(field, {region});
  const std::size_t boosted = scheduler.boostedProbes();
  ASSERT_GT(boosted, 0u);
  ASSERT_LT(boosted, field.probes.size());
  // A viewer far from the edit does not take the budget from it.
  const std::vector<glm::vec3> viewers = {{-0.9f, 1.8f, -0.9f}};
  const auto plan = scheduler.plan(field, 4, viewers);
  ASSERT_EQ(plan.size(), std::size_t(options.budget));
  const std::size_t inRegion = std::size_t(std::count_if(plan.begin(), plan.end(), [&](ProbeRef r) {
    return glm::length(field.probePosition(r.cascade, r.slot) - region.center) <= region.radius;
  }));
  EXPECT_EQ(inRegion, std::min<std::size_t>(boosted, plan.size()));
  // Without the edit the same plan goes to the viewer's corner instead.
  ProbeScheduler plain(options);
  for (std::uint64_t t = 1; t <= 3; ++t) (void)plain.plan(field, t);
  const auto viewerPlan = plain.plan(field, 4, viewers);
  const std::size_t nearEdit =
      std::size_t(std::count_if(viewerPlan.begin(), viewerPlan.end(), [&](ProbeRef r) {
        return glm::length(field.probePosition(r.cascade, r.slot) - region.center) <= region.radius;
      }));
  EXPECT_LT(nearEdit, inRegion);
}

// Sessions against a real server: the edit's answer, and what viewers' sessions apply.
class EditSessions : public ::testing::Test {
 protected:
  nettest::TestServer server{-1.0};

  client::NetClientOptions options(const std::string& name, TokenRole role) {
    client::NetClientOptions o = nettest::secureClientOptions(server, name);
    o.token = nettest::issueTestToken(name, 3600, 0, role);
    return o;
  }
  static std::optional<EditResultMsg> answer(client::NetClient& c, std::uint32_t id) {
    std::optional<EditResultMsg> out;
    nettest::waitFor(
        [&] {
          for (const EditResultMsg& r : c.takeEditResults())
            if (r.editId == id) out = r;
          return out.has_value();
        },
        10.0);
    return out;
  }
};

TEST_F(EditSessions, EditorsEditIsAppliedAndSeenByTwoViewers) {
  client::FieldMirror m0, m1, m2;
  client::NetClient editor(m0, options("editor", TokenRole::Editor));
  client::NetClient viewerA(m1, options("viewer-a", TokenRole::Viewer));
  client::NetClient viewerB(m2, options("viewer-b", TokenRole::Viewer));
  for (auto* c : {&editor, &viewerA, &viewerB}) c->start();
  ASSERT_TRUE(nettest::waitFor(
      [&] {
        return editor.stats().connected && viewerA.stats().connected && viewerB.stats().connected;
      },
      15.0));
  EXPECT_FALSE(viewerA.editedScene().has_value());  // the animation alone so far

  SceneEdit e = lightEdit(0, 5.0f);
  e.fields |= kEditColor;
  e.color = {1.0f, 0.5f, 0.2f};
  editor.sendEdit(EditMsg{1, e});
  auto result = answer(editor, 1);
  ASSERT_TRUE(result.has_value());
  EXPECT_TRUE(result->accepted) << result->reason;
  EXPECT_EQ(result->editVersion, 1u);
  EXPECT_EQ(server.editor().version(), 1u);
  for (auto* viewer : {&viewerA, &viewerB}) {
    ASSERT_TRUE(nettest::waitFor([&] { return viewer->editedScene().has_value(); }, 10.0));
    const SceneStateMsg state = *viewer->editedScene();
    EXPECT_EQ(state.editVersion, 1u);
    ASSERT_EQ(state.lights.size(), 1u);
    EXPECT_EQ(state.lights[0].intensity, 5.0f);
    EXPECT_EQ(state.lights[0].color, glm::vec3(1.0f, 0.5f, 0.2f));
    // What the client's frames draw: the server's state, not its own replay.
    SceneState drawn = evaluateScene(server.scene(), 0.0);
    ASSERT_TRUE(applySceneState(state, drawn).ok());
    EXPECT_EQ(drawn.lights[0].intensity, 5.0f);
  }
  EXPECT_EQ(server.net().stats().editsApplied, 1u);
}

TEST_F(EditSessions, ViewersEditIsRefusedAndChangesNothing) {
  client::FieldMirror m;
  client::NetClient viewer(m, options("viewer", TokenRole::Viewer));
  viewer.start();
  ASSERT_TRUE(nettest::waitFor([&] { return viewer.stats().connected; }, 15.0));
  const std::uint64_t sessions = viewer.stats().sessions;
  viewer.sendEdit(EditMsg{5, lightEdit(0, 50.0f)});
  auto result = answer(viewer, 5);
  ASSERT_TRUE(result.has_value());
  EXPECT_FALSE(result->accepted);
  EXPECT_NE(result->reason.find("editor role"), std::string::npos) << result->reason;
  nettest::sleepFor(0.3);  // a few ticks: nothing changed on the server, nothing streamed
  EXPECT_EQ(server.editor().version(), 0u);
  EXPECT_FALSE(viewer.editedScene().has_value());
  EXPECT_EQ(server.net().stats().editsDenied, 1u);
  EXPECT_TRUE(viewer.stats().connected);
  EXPECT_EQ(viewer.stats().sessions, sessions);
}

TEST_F(EditSessions, MalformedEditsAreRefusedWithTheSessionIntact) {
  client::FieldMirror m;
  client::NetClient editor(m, options("editor", TokenRole::Editor));
  editor.start();
  ASSERT_TRUE(nettest::waitFor([&] { return editor.stats().connected; }, 15.0));
  const std::uint64_t sessions = editor.stats().sessions;
  SceneEdit farAway = lightEdit(0, 1.0f);
  farAway.fields = kEditPosition;
  farAway.position = {1e30f, 0.0f, 0.0f};
  const std::vector<std::pair<SceneEdit, std::string>> cases = {
      {lightEdit(0, kNaN), "not finite"},
      {lightEdit(99, 1.0f), "does not exist"},
      {farAway, "position"},
  };
  std::uint32_t id = 10;
  for (const auto& [edit, why] : cases) {
    editor.sendEdit(EditMsg{++id, edit});
    auto result = answer(editor, id);
    ASSERT_TRUE(result.has_value()) << why;
    EXPECT_FALSE(result->accepted);
    EXPECT_NE(result->reason.find(why), std::string::npos) << result->reason;
  }
  EXPECT_EQ(server.editor().version(), 0u);
  EXPECT_EQ(server.net().stats().editsInvalid, cases.size());
  // The same session goes on, and takes a good edit.
  EXPECT_TRUE(editor.stats().connected);
  EXPECT_EQ(editor.stats().sessions, sessions);
  editor.sendEdit(EditMsg{++id, lightEdit(0, 4.0f)});
  auto good = answer(editor, id);
  ASSERT_TRUE(good.has_value());
  EXPECT_TRUE(good->accepted) << good->reason;
  EXPECT_EQ(editor.stats().sessions, sessions);
}

}  // namespace
}  // namespace pc
