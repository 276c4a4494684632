// Session messages <-> size-prefixed flatbuffers (session.fbs), with the checks that keep a
// corrupt or hostile peer from crashing either side.
#include "session_messages.h"

#include <flatbuffers/flatbuffers.h>
#include <zstd.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <iterator>

#include "common/constant_time.h"
#include "protocol/brick_precision.h"
#include "protocol/datagram.h"
#include "protocol/session_generated.h"

namespace pc {

namespace {

using namespace pc::gpu;
namespace fb = flatbuffers;

net::Vec3 toWire(glm::vec3 v) { return net::Vec3(v.x, v.y, v.z); }
net::Int3 toWire(glm::ivec3 v) { return net::Int3(v.x, v.y, v.z); }
glm::vec3 fromWire(const net::Vec3* v) {
  return v ? glm::vec3(v->x(), v->y(), v->z()) : glm::vec3(0);
}
glm::ivec3 fromWire(const net::Int3* v) {
  return v ? glm::ivec3(v->x(), v->y(), v->z()) : glm::ivec3(0);
}

bool finite(glm::vec3 v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

std::string str(const fb::String* s) { return s ? s->str() : std::string(); }

struct Encoder {
  fb::FlatBufferBuilder& fbb;

  fb::Offset<void> operator()(const HelloMsg& m) {
    auto token = fbb.CreateString(m.authToken);
    auto name = fbb.CreateString(m.clientName);
    return net::CreateHello(fbb, m.protocolVersion, token, name, m.wantsUdp, m.udpPort, m.heldEpoch)
        .Union();
  }
  fb::Offset<void> operator()(const WelcomeMsg& m) {
    return net::CreateWelcome(fbb, m.protocolVersion, m.sessionId).Union();
  }
  fb::Offset<void> operator()(const RejectMsg& m) {
    auto reason = fbb.CreateString(m.reason);
    return net::CreateReject(fbb, m.protocolVersion, reason).Union();
  }
  fb::Offset<void> operator()(const SessionInfoMsg& m) {
    std::vector<fb::Offset<net::CascadeInfo>> cascades;
    for (const CascadeDesc& c : m.cascades) {
      net::Vec3 origin = toWire(c.origin);
      net::Int3 counts = toWire(c.counts), scroll = toWire(c.scroll);
      cascades.push_back(net::CreateCascadeInfo(fbb, &origin, c.spacing, &counts, c.firstProbe,
                                                &scroll, c.atlasTileRow, c.normalBias, c.viewBias,
                                                c.maxRayDistance, c.blendMargin, c.hysteresis));
    }
    auto cascadesOff = fbb.CreateVector(cascades);
    std::vector<net::Codec> codecs;
    for (std::uint8_t c : m.codecs) codecs.push_back(net::Codec(c));
    auto codecsOff =
        fbb.CreateVector(reinterpret_cast<const std::uint8_t*>(codecs.data()), codecs.size());
    net::SessionInfoBuilder b(fbb);
    b.add_scene_hash(m.sceneHash);
    b.add_field_version(m.fieldVersion);
    b.add_irradiance_texels(m.irradianceTexels);
    b.add_depth_texels(m.depthTexels);
    b.add_occlusion_texels(m.occlusionTexels);
    b.add_brick_size(m.brickSize);
    b.add_atlas_tiles_per_row(m.atlasTilesPerRow);
    b.add_hysteresis(m.hysteresis);
    b.add_distance_exponent(m.distanceExponent);
    b.add_occlusion_distance(m.occlusionDistance);
    b.add_cascades(cascadesOff);
    b.add_codecs(fb::Offset<fb::Vector<net::Codec>>(codecsOff.o));
    b.add_max_datagram_bytes(m.maxDatagramBytes);
    b.add_uplink_port(m.uplinkPort);
    b.add_field_epoch(m.fieldEpoch);
    return b.Finish().Union();
  }
  fb::Offset<void> operator()(const SceneStateMsg& m) {
    std::vector<fb::Offset<net::LightState>> lights;
    for (const LightStateMsg& l : m.lights) {
      net::Vec3 p = toWire(l.position), d = toWire(l.direction), c = toWire(l.color);
      lights.push_back(net::CreateLightState(fbb, &p, &d, &c, l.intensity, l.added, l.range));
    }
    auto lightsOff = fbb.CreateVector(lights);
    std::vector<net::Mat4> mats;
    for (const glm::mat4& t : m.instanceTransforms) {
      mats.emplace_back(fb::span<const float, 16>(&t[0][0], 16));
    }
    auto matsOff = fbb.CreateVectorOfStructs(mats);
    fb::Offset<fb::Vector<float>> emissionOff;
    if (!m.emissionScales.empty()) emissionOff = fbb.CreateVector(m.emissionScales);
    fb::Offset<fb::Vector<const net::CascadePlace*>> placesOff;
    if (!m.cascadePlaces.empty()) {
      std::vector<net::CascadePlace> places;
      for (const CascadePlaceMsg& p : m.cascadePlaces)
        places.emplace_back(toWire(p.origin), toWire(p.scroll));
      placesOff = fbb.CreateVectorOfStructs(places);
    }
    return net::CreateSceneState(fbb, m.animationTime, lightsOff, matsOff, m.fieldVersion,
                                 m.publishTime, m.editVersion, emissionOff, placesOff)
        .Union();
  }
  fb::Offset<void> operator()(const EditMsg& m) {
    const SceneEdit& e = m.edit;
    net::Vec3 p = toWire(e.position), d = toWire(e.direction), c = toWire(e.color);
    net::Mat4 t(fb::span<const float, 16>(&e.transform[0][0], 16));
    return net::CreateEdit(fbb, m.editId, net::EditOp(e.op), e.target, e.fields, &p, &d, &c,
                           e.intensity, e.range, &t, e.emission)
        .Union();
  }
  fb::Offset<void> operator()(const EditResultMsg& m) {
    auto reason = fbb.CreateString(m.reason);
    return net::CreateEditResult(fbb, m.editId, m.accepted, reason, m.editVersion, m.target)
        .Union();
  }
  fb::Offset<void> operator()(const ViewerPoseMsg& m) {
    net::Vec3 p = toWire(m.position);
    net::Quat q(m.orientation.x, m.orientation.y, m.orientation.z, m.orientation.w);
    return net::CreateViewerPose(fbb, &p, &q, m.time).Union();
  }
  fb::Offset<void> operator()(const AckMsg& m) {
    std::vector<net::AckRange> ranges;
    for (const AckRange& r : m.ranges) {
      ranges.emplace_back(r.version, r.firstBrick, r.count, std::uint8_t(r.cascade));
    }
    auto rangesOff = fbb.CreateVectorOfStructs(ranges);
    fb::Offset<fb::Vector<fb::Offset<net::FragmentGap>>> gapsOff;
    if (!m.gaps.empty()) {
      std::vector<fb::Offset<net::FragmentGap>> gaps;
      for (const FragmentGapMsg& g : m.gaps) {
        gaps.push_back(net::CreateFragmentGap(fbb, g.updateId, std::uint8_t(g.cascade), g.brick,
                                              g.version, g.baseVersion, g.fragmentCount,
                                              fbb.CreateVector(g.missing)));
      }
      gapsOff = fbb.CreateVector(gaps);
    }
    fb::Offset<fb::Vector<const net::DatagramArrival*>> arrivalsOff;
    if (!m.arrivals.empty()) {
      std::vector<net::DatagramArrival> arrivals;
      arrivals.reserve(m.arrivals.size());
      for (const DatagramArrivalMsg& a : m.arrivals)
        arrivals.emplace_back(a.sequence, a.arrivalMicros);
      arrivalsOff = fbb.CreateVectorOfStructs(arrivals);
    }
    fb::Offset<fb::Vector<const net::BrickPrecision*>> precisionsOff;
    if (!m.precisions.empty()) {
      std::vector<net::BrickPrecision> precisions;
      precisions.reserve(m.precisions.size());
      for (const BrickPrecisionMsg& p : m.precisions)
        precisions.emplace_back(p.brick, std::uint8_t(p.cascade), std::uint8_t(p.precision));
      precisionsOff = fbb.CreateVectorOfStructs(precisions);
    }
    return net::CreateAck(fbb, m.full, m.fieldVersion, rangesOff, gapsOff, arrivalsOff,
                          precisionsOff)
        .Union();
  }
  fb::Offset<void> operator()(const StreamReportMsg& m) {
    return net::CreateStreamReport(fbb, m.rate, m.delivered, m.queueDelayMs, m.loss,
                                   std::uint8_t(std::clamp(m.qualityLevel, 0, 255)), m.heldPsnrDb,
                                   m.oldestChangeSeconds, m.pendingBricks, m.fieldVersion)
        .Union();
  }
  fb::Offset<void> operator()(const RepairRequestMsg& m) {
    std::vector<net::BrickRef> refs;
    for (const BrickRefMsg& r : m.bricks) {
      refs.emplace_back(r.haveVersion, r.brick, std::uint8_t(r.cascade));
    }
    auto refsOff = fbb.CreateVectorOfStructs(refs);
    fb::Offset<fb::Vector<std::uint8_t>> precisionsOff;
    const bool coarse = std::any_of(m.bricks.begin(), m.bricks.end(),
                                    [](const BrickRefMsg& r) { return r.havePrecision != 0; });
    if (coarse) {
      std::vector<std::uint8_t> precisions;
      precisions.reserve(m.bricks.size());
      for (const BrickRefMsg& r : m.bricks) precisions.push_back(std::uint8_t(r.havePrecision));
      precisionsOff = fbb.CreateVector(precisions);
    }
    return net::CreateRepairRequest(fbb, refsOff, precisionsOff).Union();
  }
  fb::Offset<void> operator()(const ResumeMsg& m) {
    auto versionsOff = fbb.CreateVector(m.versions);
    std::vector<net::BrickPrecision> precisions;
    precisions.reserve(m.precisions.size());
    for (const BrickPrecisionMsg& p : m.precisions)
      precisions.emplace_back(p.brick, std::uint8_t(p.cascade), std::uint8_t(p.precision));
    auto precisionsOff = fbb.CreateVectorOfStructs(precisions);
    return net::CreateResume(fbb, m.sceneHash, m.fieldEpoch, m.brickCount, versionsOff,
                             precisionsOff)
        .Union();
  }
};

net::Body bodyType(const SessionMessage& m) {
  // The variant's alternatives are in the union's order, which starts at 1 (0 is NONE).
  return net::Body(m.index() + 1);
}

Error fail(const std::string& what) { return Error{"session message: " + what}; }

Result<SessionMessage> decodeSessionInfo(const net::SessionInfo& w) {
  SessionInfoMsg m;
  m.sceneHash = w.scene_hash();
  m.fieldVersion = w.field_version();
  m.irradianceTexels = w.irradiance_texels();
  m.depthTexels = w.depth_texels();
  m.occlusionTexels = w.occlusion_texels();
  m.brickSize = w.brick_size();
  m.atlasTilesPerRow = w.atlas_tiles_per_row();
  m.hysteresis = w.hysteresis();
  m.distanceExponent = w.distance_exponent();
  m.occlusionDistance = w.occlusion_distance();
  m.maxDatagramBytes = w.max_datagram_bytes();
  m.uplinkPort = w.uplink_port();
  m.fieldEpoch = w.field_epoch();
  if (w.cascades() && w.cascades()->size() > std::size_t(PC_MAX_CASCADES)) {
    return fail("session info: " + std::to_string(w.cascades()->size()) + " cascades, at most " +
                std::to_string(PC_MAX_CASCADES) + " supported");
  }
  if (w.cascades()) {
    for (const net::CascadeInfo* c : *w.cascades()) {
      CascadeDesc d{};
      d.origin = fromWire(c->origin());
      d.spacing = c->spacing();
      d.counts = fromWire(c->counts());
      d.firstProbe = c->first_probe();
      d.scroll = fromWire(c->scroll());
      d.atlasTileRow = c->atlas_tile_row();
      d.normalBias = c->normal_bias();
      d.viewBias = c->view_bias();
      d.maxRayDistance = c->max_ray_distance();
      d.blendMargin = c->blend_margin();
      d.hysteresis = c->hysteresis() < 0.0f ? m.hysteresis : c->hysteresis();
      m.cascades.push_back(d);
    }
  }
  m.codecs.clear();
  if (w.codecs()) {
    for (auto c : *w.codecs()) m.codecs.push_back(std::uint8_t(c));
  }
  return SessionMessage(std::move(m));
}

// Bounded here, before anything else reads it: the brick count by the largest field a layout
// may have, the compressed versions by what zstd makes of one uint64 per brick at worst, one
// precision per brick. resume_state.h checks the rest against the field.
Result<SessionMessage> decodeResume(const net::Resume& w) {
  ResumeMsg m;
  m.sceneHash = w.scene_hash();
  m.fieldEpoch = w.field_epoch();
  m.brickCount = w.brick_count();
  if (m.brickCount > kMaxResumeBricks) {
    return fail("resume: " + std::to_string(m.brickCount) + " bricks (at most " +
                std::to_string(kMaxResumeBricks) + ")");
  }
  if (w.versions()) {
    const std::size_t bound = ZSTD_COMPRESSBOUND(std::size_t(m.brickCount) * 8);
    if (w.versions()->size() > bound) {
      return fail("resume: " + std::to_string(w.versions()->size()) + " bytes of versions for " +
                  std::to_string(m.brickCount) + " bricks (at most " + std::to_string(bound) + ")");
    }
    m.versions.assign(w.versions()->begin(), w.versions()->end());
  }
  if (w.precisions()) {
    if (w.precisions()->size() > m.brickCount) {
      return fail("resume: " + std::to_string(w.precisions()->size()) + " precisions for " +
                  std::to_string(m.brickCount) + " bricks");
    }
    for (const net::BrickPrecision* p : *w.precisions()) {
      if (p->precision() > kMaxPrecision) {
        return fail("resume: precision level " + std::to_string(p->precision()) +
                    " (the coarsest is " + std::to_string(kMaxPrecision) + ")");
      }
      m.precisions.push_back(BrickPrecisionMsg{p->cascade(), p->brick(), p->precision()});
    }
  }
  return SessionMessage(std::move(m));
}

}  // namespace

std::vector<std::uint8_t> encodeMessage(const SessionMessage& message) {
  fb::FlatBufferBuilder fbb(256);
  auto body = std::visit(Encoder{fbb}, message);
  auto root = net::CreateSessionMessage(fbb, bodyType(message), body);
  net::FinishSizePrefixedSessionMessageBuffer(fbb, root);
  return std::vector<std::uint8_t>(fbb.GetBufferPointer(), fbb.GetBufferPointer() + fbb.GetSize());
}

const char* sessionMessageName(const SessionMessage& message) {
  constexpr const char* kNames[] = {"Hello",        "Welcome",    "Reject", "SessionInfo",
                                    "SceneState",   "ViewerPose", "Ack",    "RepairRequest",
                                    "StreamReport", "Resume",     "Edit",   "EditResult"};
  static_assert(std::size(kNames) == std::variant_size_v<SessionMessage>);
  return kNames[message.index()];
}

Result<std::size_t> messageFrameSize(std::span<const std::uint8_t> prefix) {
  if (prefix.size() < 4) return fail("size prefix needs 4 bytes");
  std::uint32_t n;
  std::memcpy(&n, prefix.data(), 4);  // little-endian hosts only, like flatbuffers itself
  const std::size_t total = std::size_t(n) + 4;
  if (total > kMaxSessionMessageBytes) {
    return fail("announces " + std::to_string(total) + " bytes, limit " +
                std::to_string(kMaxSessionMessageBytes));
  }
  if (n < 8) return fail("announces " + std::to_string(n) + " bytes, too short for a message");
  return total;
}

Result<SessionMessage> decodeMessage(std::span<const std::uint8_t> frame) {
  auto size = messageFrameSize(frame);
  if (!size) return size.error();
  if (*size != frame.size()) {
    return fail("frame of " + std::to_string(frame.size()) + " bytes announces " +
                std::to_string(*size));
  }
  if (!fb::BufferHasIdentifier(frame.data(), net::SessionMessageIdentifier(), true)) {
    return fail("not a session message (wrong identifier)");
  }
  // The Verifier checks alignment against the address; callers may hand in any span.
  std::vector<std::uint8_t> aligned;
  const std::uint8_t* data = frame.data();
  if (reinterpret_cast<std::uintptr_t>(data) % 8 != 0) {
    aligned.assign(frame.begin(), frame.end());
    data = aligned.data();
  }
  fb::Verifier::Options opts;
  opts.max_depth = kMaxMessageDepth;
  opts.max_tables = kMaxMessageTables;
  fb::Verifier v(data, frame.size(), opts);
  if (!net::VerifySizePrefixedSessionMessageBuffer(v)) {
    return fail("corrupt (flatbuffer verification failed)");
  }
  const net::SessionMessage* root = net::GetSizePrefixedSessionMessage(data);
  // The Verifier accepts a union type without its table; nothing below may assume one.
  if (root->body() == nullptr) return fail("message without a body");
  switch (root->body_type()) {
    case net::Body::Hello: {
      const auto* w = root->body_as_Hello();
      HelloMsg m;
      m.protocolVersion = w->protocol_version();
      m.authToken = str(w->auth_token());
      m.clientName = str(w->client_name());
      m.wantsUdp = w->wants_udp();
      m.udpPort = w->udp_port();
      m.heldEpoch = w->held_epoch();
      return SessionMessage(std::move(m));
    }
    case net::Body::Welcome: {
      const auto* w = root->body_as_Welcome();
      return SessionMessage(WelcomeMsg{w->protocol_version(), w->session_id()});
    }
    case net::Body::Reject: {
      const auto* w = root->body_as_Reject();
      return SessionMessage(RejectMsg{w->protocol_version(), str(w->reason())});
    }
    case net::Body::SessionInfo:
      return decodeSessionInfo(*root->body_as_SessionInfo());
    case net::Body::SceneState: {
      const auto* w = root->body_as_SceneState();
      SceneStateMsg m;
      m.animationTime = w->animation_time();
      if (!std::isfinite(m.animationTime)) return fail("scene state: animation time not finite");
      m.fieldVersion = w->field_version();
      m.publishTime = w->publish_time();
      if (!std::isfinite(m.publishTime)) return fail("scene state: publish time not finite");
      if (w->lights()) {
        for (const net::LightState* l : *w->lights()) {
          LightStateMsg s{fromWire(l->position()),
                          fromWire(l->direction()),
                          fromWire(l->color()),
                          l->intensity(),
                          l->added(),
                          l->range()};
          if (!finite(s.position) || !finite(s.direction) || !finite(s.color) ||
              !std::isfinite(s.intensity) || !std::isfinite(s.range)) {
            return fail("scene state: light values not finite");
          }
          m.lights.push_back(s);
        }
      }
      if (w->instance_transforms()) {
        for (const net::Mat4* t : *w->instance_transforms()) {
          glm::mat4 mat;
          for (int i = 0; i < 16; ++i) {
            const float x = t->m()->Get(i);
            if (!std::isfinite(x)) return fail("scene state: instance transform not finite");
            (&mat[0][0])[i] = x;
          }
          m.instanceTransforms.push_back(mat);
        }
      }
      m.editVersion = w->edit_version();
      if (w->emission_scales()) {
        if (w->emission_scales()->size() > kMaxEmissionScales)
          return fail("scene state: " + std::to_string(w->emission_scales()->size()) +
                      " emission factors (at most " + std::to_string(kMaxEmissionScales) + ")");
        for (float f : *w->emission_scales()) {
          if (!std::isfinite(f) || f < 0.0f)
            return fail("scene state: emission factor " + std::to_string(f) + " not finite or < 0");
          m.emissionScales.push_back(f);
        }
      }
      if (w->cascade_places()) {
        if (w->cascade_places()->size() > std::size_t(PC_MAX_CASCADES))
          return fail("scene state: " + std::to_string(w->cascade_places()->size()) +
                      " cascade places (at most " + std::to_string(PC_MAX_CASCADES) + ")");
        for (const net::CascadePlace* p : *w->cascade_places()) {
          CascadePlaceMsg place{fromWire(&p->origin()), fromWire(&p->scroll())};
          if (!finite(place.origin)) return fail("scene state: cascade origin not finite");
          m.cascadePlaces.push_back(place);
        }
      }
      return SessionMessage(std::move(m));
    }
    case net::Body::ViewerPose: {
      const auto* w = root->body_as_ViewerPose();
      ViewerPoseMsg m;
      m.position = fromWire(w->position());
      if (w->orientation()) {
        const auto* q = w->orientation();
        m.orientation = glm::quat(q->w(), q->x(), q->y(), q->z());
      }
      m.time = w->time();
      if (!finite(m.position) || !std::isfinite(m.time) || !std::isfinite(m.orientation.x) ||
          !std::isfinite(m.orientation.y) || !std::isfinite(m.orientation.z) ||
          !std::isfinite(m.orientation.w)) {
        return fail("viewer pose: values not finite");
      }
      return SessionMessage(m);
    }
    case net::Body::Ack: {
      const auto* w = root->body_as_Ack();
      AckMsg m;
      m.full = w->full();
      m.fieldVersion = w->field_version();
      if (w->ranges()) {
        m.ranges.reserve(w->ranges()->size());
        for (const net::AckRange* p : *w->ranges()) {
          // Structs of 8-byte fields may sit at 4-byte boundaries (the Verifier checks only the
          // vector's length field): copy each out before reading it.
          net::AckRange copy;
          std::memcpy(&copy, p, sizeof copy);
          const net::AckRange* r = &copy;
          m.ranges.push_back(AckRange{r->cascade(), r->first_brick(), r->count(), r->version()});
        }
      }
      if (w->gaps()) {
        if (w->gaps()->size() > kMaxFragmentGaps) {
          return fail("ack: " + std::to_string(w->gaps()->size()) + " fragment gaps (at most " +
                      std::to_string(kMaxFragmentGaps) + ")");
        }
        for (const net::FragmentGap* g : *w->gaps()) {
          FragmentGapMsg gap{g->update_id(),    g->cascade(),        g->brick(), g->version(),
                             g->base_version(), g->fragment_count(), {}};
          if (gap.fragmentCount < 2 || gap.fragmentCount > fragmentCount(kMaxUpdatePayloadBytes))
            return fail("ack: fragment gap of an update of " + std::to_string(gap.fragmentCount) +
                        " fragments");
          if (g->missing()) {
            if (g->missing()->size() > gap.fragmentCount)
              return fail("ack: fragment gap lists more fragments than its update has");
            for (std::uint16_t i : *g->missing()) {
              if (i >= gap.fragmentCount)
                return fail("ack: fragment gap names fragment " + std::to_string(i) + " of " +
                            std::to_string(gap.fragmentCount));
              gap.missing.push_back(i);
            }
          }
          m.gaps.push_back(std::move(gap));
        }
      }
      if (w->arrivals()) {
        if (w->arrivals()->size() > kMaxAckArrivals) {
          return fail("ack: " + std::to_string(w->arrivals()->size()) +
                      " datagram arrivals (at most " + std::to_string(kMaxAckArrivals) + ")");
        }
        m.arrivals.reserve(w->arrivals()->size());
        for (const net::DatagramArrival* a : *w->arrivals())
          m.arrivals.push_back(DatagramArrivalMsg{a->sequence(), a->arrival_us()});
      }
      if (w->precisions()) {
        // At most one entry per listed brick.
        std::uint64_t listed = 0;
        for (const AckRange& r : m.ranges) listed += r.count;
        if (w->precisions()->size() > listed) {
          return fail("ack: " + std::to_string(w->precisions()->size()) + " brick precisions for " +
                      std::to_string(listed) + " bricks listed");
        }
        m.precisions.reserve(w->precisions()->size());
        for (const net::BrickPrecision* p : *w->precisions()) {
          if (p->precision() > kMaxPrecision) {
            return fail("ack: precision level " + std::to_string(p->precision()) +
                        " (the coarsest is " + std::to_string(kMaxPrecision) + ")");
          }
          m.precisions.push_back(BrickPrecisionMsg{p->cascade(), p->brick(), p->precision()});
        }
      }
      return SessionMessage(std::move(m));
    }
    case net::Body::RepairRequest: {
      const auto* w = root->body_as_RepairRequest();
      RepairRequestMsg m;
      if (w->bricks()) {
        m.bricks.reserve(w->bricks()->size());
        for (const net::BrickRef* p : *w->bricks()) {
          net::BrickRef copy;  // possibly misaligned in the buffer, as above
          std::memcpy(&copy, p, sizeof copy);
          const net::BrickRef* r = &copy;
          m.bricks.push_back(BrickRefMsg{r->cascade(), r->brick(), r->have_version(), 0});
        }
        if (const auto* precisions = w->have_precisions(); precisions && precisions->size() > 0) {
          if (precisions->size() != m.bricks.size()) {
            return fail("repair request: " + std::to_string(precisions->size()) +
                        " precisions for " + std::to_string(m.bricks.size()) + " bricks");
          }
          for (std::size_t i = 0; i < m.bricks.size(); ++i) {
            const std::uint8_t p = precisions->Get(flatbuffers::uoffset_t(i));
            if (p > kMaxPrecision) {
              return fail("repair request: precision level " + std::to_string(p) +
                          " (the coarsest is " + std::to_string(kMaxPrecision) + ")");
            }
            m.bricks[i].havePrecision = p;
          }
        }
      }
      return SessionMessage(std::move(m));
    }
    case net::Body::StreamReport: {
      const auto* w = root->body_as_StreamReport();
      StreamReportMsg m;
      m.rate = w->rate();
      m.delivered = w->delivered();
      m.queueDelayMs = w->queue_delay_ms();
      m.loss = w->loss();
      m.qualityLevel = w->quality_level();
      m.heldPsnrDb = w->held_psnr_db();
      m.oldestChangeSeconds = w->oldest_change_s();
      m.pendingBricks = w->pending_bricks();
      m.fieldVersion = w->field_version();
      if (!std::isfinite(m.rate) || !std::isfinite(m.delivered) || !std::isfinite(m.queueDelayMs) ||
          !std::isfinite(m.loss) || !std::isfinite(m.heldPsnrDb) ||
          !std::isfinite(m.oldestChangeSeconds))
        return fail("stream report: values not finite");
      return SessionMessage(m);
    }
    case net::Body::Resume:
      return decodeResume(*root->body_as_Resume());
    case net::Body::Edit: {
      // Values are SceneEdits' to bound (an EditResult names what was wrong); only what no
      // edit can be is refused here.
      const auto* w = root->body_as_Edit();
      const auto op = std::uint8_t(w->op());
      if (op == 0 || op > kLastEditOp) return fail("edit: unknown operation " + std::to_string(op));
      EditMsg m;
      m.editId = w->edit_id();
      m.edit.op = EditOp(op);
      m.edit.target = w->target();
      m.edit.fields = w->fields();
      m.edit.position = fromWire(w->position());
      m.edit.direction = fromWire(w->direction());
      m.edit.color = fromWire(w->color());
      m.edit.intensity = w->intensity();
      m.edit.range = w->range();
      if (w->transform())
        std::memcpy(&m.edit.transform[0][0], w->transform()->m()->data(), 16 * sizeof(float));
      m.edit.emission = w->emission();
      return SessionMessage(m);
    }
    case net::Body::EditResult: {
      const auto* w = root->body_as_EditResult();
      EditResultMsg m{w->edit_id(), w->accepted(), str(w->reason()), w->edit_version(),
                      w->target()};
      if (m.reason.size() > kMaxEditReasonBytes) m.reason.resize(kMaxEditReasonBytes);
      return SessionMessage(std::move(m));
    }
    case net::Body::NONE:
      break;
  }
  return fail("unknown message type " + std::to_string(int(root->body_type())));
}

HelloVerdict checkHello(const HelloMsg& hello, const TokenVerifier& verifier,
                        std::string_view scene, std::int64_t nowUnix) {
  HelloVerdict verdict;
  if (hello.protocolVersion < kMinProtocolVersion || hello.protocolVersion > kProtocolVersion) {
    verdict.versionMismatch = true;
    verdict.reject =
        RejectMsg{kProtocolVersion, "protocol version " + std::to_string(hello.protocolVersion) +
                                        " is not supported (this server speaks " +
                                        std::to_string(kMinProtocolVersion) + ".." +
                                        std::to_string(kProtocolVersion) + ")"};
    return verdict;
  }
  // A signature check, not a comparison with a secret: nothing to learn from its timing. The
  // client learns the cause (an expired token is worth renewing, a forged one is not), never
  // more than the cause's name.
  TokenError cause{};
  auto claims = verifier.verify(hello.authToken, scene, nowUnix, &cause);
  if (!claims) {
    verdict.tokenError = cause;
    verdict.reject =
        RejectMsg{kProtocolVersion, "authentication failed: " + std::string(tokenErrorName(cause))};
    return verdict;
  }
  verdict.claims = std::move(claims).value();
  return verdict;
}

Status checkServerVersion(std::uint32_t serverVersion) {
  if (serverVersion < kMinProtocolVersion || serverVersion > kProtocolVersion) {
    return Error{"server speaks protocol version " + std::to_string(serverVersion) +
                 ", this client " + std::to_string(kMinProtocolVersion) + ".." +
                 std::to_string(kProtocolVersion)};
  }
  return Status::success();
}

SessionInfoMsg sessionInfoFor(const Field& field) {
  SessionInfoMsg m;
  m.sceneHash = field.sceneHash;
  m.fieldVersion = field.version;
  m.hysteresis = field.desc.hysteresis;
  m.distanceExponent = field.desc.distanceExponent;
  m.occlusionDistance = field.desc.occlusionDistance;
  for (int k = 0; k < field.cascadeCount(); ++k) m.cascades.push_back(field.cascade(k));
  return m;
}

Result<Field> mirrorField(const SessionInfoMsg& info) {
  auto bad = [](const std::string& what) { return Error{"session info: " + what}; };
  if (info.irradianceTexels != PC_IRRADIANCE_TEXELS || info.depthTexels != PC_DEPTH_TEXELS ||
      info.occlusionTexels != PC_OCCLUSION_TEXELS || info.brickSize != PC_BRICK_SIZE ||
      info.atlasTilesPerRow != PC_ATLAS_TILES_PER_ROW) {
    return bad("the server's tile layout (" + std::to_string(info.irradianceTexels) + "/" +
               std::to_string(info.depthTexels) + "/" + std::to_string(info.occlusionTexels) +
               " texels, brick " + std::to_string(info.brickSize) + ", " +
               std::to_string(info.atlasTilesPerRow) + " tiles per row) differs from this build's");
  }
  if (info.cascades.empty() || info.cascades.size() > std::size_t(PC_MAX_CASCADES)) {
    return bad(std::to_string(info.cascades.size()) + " cascades");
  }
  bool hasCodec = false;
  for (std::uint8_t c : info.codecs) hasCodec |= c == kCodecQuantZstd;
  if (!hasCodec) return bad("the server offers no codec this client decodes");
  if (info.maxDatagramBytes < 512 || info.maxDatagramBytes > 65507) {
    return bad("max datagram size " + std::to_string(info.maxDatagramBytes));
  }
  if (!std::isfinite(info.hysteresis) || !std::isfinite(info.distanceExponent) ||
      !(info.occlusionDistance >= 0.0f) || !std::isfinite(info.occlusionDistance)) {
    return bad("field parameters not finite");
  }
  // Lay out with Field::create, then check that the server's running totals agree with ours.
  std::vector<ProbeVolume> volumes;
  std::int64_t slots = 0;
  for (std::size_t k = 0; k < info.cascades.size(); ++k) {
    const CascadeDesc& c = info.cascades[k];
    const std::string name = "cascade " + std::to_string(k) + ": ";
    if (c.counts.x < 1 || c.counts.y < 1 || c.counts.z < 1 || c.counts.x > 1024 ||
        c.counts.y > 1024 || c.counts.z > 1024) {
      return bad(name + "probe counts out of range");
    }
    slots += std::int64_t(c.counts.x + 3) * (c.counts.y + 3) * (c.counts.z + 3);
    if (slots > (std::int64_t(1) << 22)) return bad("more than 4M probe slots");
    if (!(c.spacing > 0.0f) || !std::isfinite(c.spacing) || !finite(c.origin)) {
      return bad(name + "bad origin or spacing");
    }
    if (!(c.maxRayDistance > 0.0f) || !std::isfinite(c.maxRayDistance) || !(c.normalBias >= 0.0f) ||
        !(c.viewBias >= 0.0f) || !(c.blendMargin >= 0.0f) || !std::isfinite(c.normalBias) ||
        !std::isfinite(c.viewBias) || !std::isfinite(c.blendMargin)) {
      return bad(name + "bad distances or biases");
    }
    if (c.scroll.x < 0 || c.scroll.y < 0 || c.scroll.z < 0 || c.scroll.x >= c.counts.x ||
        c.scroll.y >= c.counts.y || c.scroll.z >= c.counts.z) {
      return bad(name + "scroll out of range");
    }
    volumes.push_back(ProbeVolume{c.origin, c.spacing, c.counts});
  }
  Field f = Field::create(volumes, FieldSettings{});
  for (std::size_t k = 0; k < info.cascades.size(); ++k) {
    const CascadeDesc& c = info.cascades[k];
    if (c.firstProbe != f.desc.cascades[k].firstProbe ||
        c.atlasTileRow != f.desc.cascades[k].atlasTileRow) {
      return bad("cascade " + std::to_string(k) +
                 ": first probe or atlas row disagrees with the layout");
    }
    f.desc.cascades[k] = c;
  }
  f.desc.hysteresis = info.hysteresis;
  f.desc.distanceExponent = info.distanceExponent;
  f.desc.occlusionDistance = info.occlusionDistance;
  f.sceneHash = info.sceneHash;
  f.version = 0;
  return f;
}

std::vector<CascadePlaceMsg> cascadePlaces(const Field& field) {
  std::vector<CascadePlaceMsg> places;
  bool follows = false;
  for (int k = 0; k < field.cascadeCount(); ++k) {
    follows |= field.cascade(k).follows != 0;
    places.push_back({field.cascade(k).origin, field.cascade(k).scroll});
  }
  if (!follows) places.clear();
  return places;
}

SceneStateMsg sceneStateMessage(const SceneState& state) {
  SceneStateMsg m;
  m.animationTime = state.time;
  const std::size_t firstAdded =
      state.lights.size() - std::min<std::size_t>(state.addedLights, state.lights.size());
  for (std::size_t i = 0; i < state.lights.size(); ++i) {
    const Light& l = state.lights[i];
    m.lights.push_back(
        LightStateMsg{l.position, l.direction, l.color, l.intensity, i >= firstAdded, l.range});
  }
  m.instanceTransforms = state.instanceTransforms;
  m.editVersion = state.editVersion;
  m.emissionScales = state.emissionScale;
  return m;
}

Status applySceneState(const SceneStateMsg& message, SceneState& state) {
  // The scene's own lights come first, then those edits added (point lights): the scene
  // holds the first kind's types and cones, the message the second's.
  std::size_t sceneLights =
      state.lights.size() - std::min<std::size_t>(state.addedLights, state.lights.size());
  std::size_t added = 0;
  for (std::size_t i = 0; i < message.lights.size(); ++i) {
    if (message.lights[i].added != (i >= sceneLights)) {
      return Error{"scene state: light " + std::to_string(i) +
                   (message.lights[i].added ? " is an added one" : " is not an added one") +
                   ", the scene has " + std::to_string(sceneLights) + " lights of its own"};
    }
    added += message.lights[i].added ? 1 : 0;
  }
  if (message.lights.size() - added != sceneLights || added > kMaxAddedLights ||
      message.instanceTransforms.size() != state.instanceTransforms.size()) {
    return Error{"scene state: " + std::to_string(message.lights.size()) + " lights (" +
                 std::to_string(added) + " added) and " +
                 std::to_string(message.instanceTransforms.size()) + " instances, the scene has " +
                 std::to_string(sceneLights) + " and " +
                 std::to_string(state.instanceTransforms.size())};
  }
  state.time = message.animationTime;
  state.lights.resize(sceneLights);
  for (std::size_t i = 0; i < message.lights.size(); ++i) {
    const LightStateMsg& m = message.lights[i];
    if (i >= sceneLights) {
      Light l;
      l.name = "edit " + std::to_string(i - sceneLights);
      l.type = LightType::Point;
      l.range = std::max(0.0f, m.range);
      state.lights.push_back(l);
    } else if (message.editVersion > 0) {
      state.lights[i].range = std::max(0.0f, m.range);
    }
    state.lights[i].position = m.position;
    state.lights[i].direction = m.direction;
    state.lights[i].color = m.color;
    state.lights[i].intensity = m.intensity;
  }
  state.addedLights = std::uint32_t(added);
  state.instanceTransforms = message.instanceTransforms;
  state.editVersion = message.editVersion;
  state.emissionScale = message.emissionScales;
  return Status::success();
}

}  // namespace pc
