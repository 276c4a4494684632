#include "client_session.h"

#include <algorithm>

#include "common/log.h"
#include "protocol/brick_codec.h"
#include "protocol/net_framing.h"
#include "protocol/resume_state.h"

namespace pc {

namespace {
// Datagrams poll() made that the caller has not taken: beyond this the oldest go (an ack's
// news is repeated by the next ones anyway).
constexpr std::size_t kMaxQueuedUplinkDatagrams = 256;
}  // namespace

std::uint64_t mirrorMemoryBytes(const SessionInfoMsg& info) {
  using namespace gpu;
  constexpr std::uint64_t kTileFloats =
      std::uint64_t(PC_IRRADIANCE_TEXELS + 2) * (PC_IRRADIANCE_TEXELS + 2) * 3 +
      std::uint64_t(PC_DEPTH_TEXELS + 2) * (PC_DEPTH_TEXELS + 2) * 2 +
      std::uint64_t(PC_OCCLUSION_TEXELS + 2) * (PC_OCCLUSION_TEXELS + 2);
  constexpr std::uint64_t kSlotBytes = kTileFloats * sizeof(float) + sizeof(ProbeRecord);
  constexpr std::uint64_t kBrickCodeBytes = brick_layout::kCodes * sizeof(std::uint16_t);
  std::uint64_t bricks = 0;
  for (const CascadeDesc& c : info.cascades) {
    const auto perAxis = [](int n) { return std::uint64_t(std::clamp(n, 1, 1024) + 3) / 4; };
    bricks += perAxis(c.counts.x) * perAxis(c.counts.y) * perAxis(c.counts.z);
  }
  const std::uint64_t slots = bricks * PC_PROBES_PER_BRICK;
  // Two fields (the receiver's and the renderer's mirror) and one set of codes.
  return 2 * slots * kSlotBytes + bricks * kBrickCodeBytes;
}

void AnimationClock::update(double animationTime, double now) {
  if (known_ && now > wall_ + 1e-3) {
    // The rate the server's clock advanced at (0 when it is frozen), so extrapolating between
    // states never runs past a stopped clock. Clamped: jitter only nudges it.
    rate_ = std::clamp((animationTime - animation_) / (now - wall_), 0.0, 2.0);
  }
  known_ = true;
  animation_ = animationTime;
  wall_ = now;
}

std::optional<double> AnimationClock::at(double now) const {
  if (!known_) return std::nullopt;
  // While the server is away the clock runs on at the last rate: the scene keeps moving and
  // the next scene state corrects it.
  return animation_ + rate_ * (now - wall_);
}

ClientSession::ClientSession(ClientSessionOptions options) : options_(std::move(options)) {}

bool ClientSession::connectedPhase() const {
  return phase_ == SessionPhase::AwaitingWelcome || phase_ == SessionPhase::AwaitingLayout ||
         phase_ == SessionPhase::Streaming;
}

void ClientSession::connecting(double now) {
  close();
  phase_ = SessionPhase::Connecting;
  connectStartedAt_ = now;
  error_.clear();
  sessionId_ = 0;
  editsOut_.clear();  // an edit is answered in the session it was sent in, or not at all
  ++stats_.connectAttempts;
}

std::vector<std::uint8_t> ClientSession::connected(double now, std::uint16_t udpPort) {
  phase_ = SessionPhase::AwaitingWelcome;
  lastHeard_ = now;
  HelloMsg hello;
  hello.authToken = options_.token;
  hello.clientName = options_.name;
  hello.wantsUdp = udpPort != 0;
  hello.udpPort = udpPort;
  // The field the previous session left (if any): a server of the same epoch waits for the
  // Resume that says what of it this client holds.
  heldEpoch_ = keptReceiver_ ? keptInfo_.fieldEpoch : 0;
  hello.heldEpoch = heldEpoch_;
  return encodeMessage(hello);
}

void ClientSession::close() {
  phase_ = SessionPhase::Idle;
  // What the session held stays for the next one to resume from (protocol version 7): the
  // brick versions and their codes, the bases of the residuals the next server may send.
  if (receiver_ && options_.resume && info_.fieldEpoch != 0) {
    keptReceiver_ = std::move(receiver_);
    keptInfo_ = info_;
  }
  receiver_.reset();
  resumeFrame_.clear();
  frame_ = {};  // released: a server may have sent one frame of megabytes
  frameBytes_ = 0;
  early_.clear();
  earlySealed_.clear();
  datagramKey_.reset();
  opener_.reset();
  uplinkKey_.reset();
  spokenVersion_ = 0;
  uplink_.reset();
  uplinkOut_.clear();
  events_.clear();
  held_.clear();
  changed_.clear();
  changedList_.clear();
  lastApplied_ = 0;
  bricksHeld_ = bricksTotal_ = 0;
  synced_ = false;
  report_.reset();
  serverUdpPort_ = 0;
}

Error ClientSession::fail(std::string why, SessionPhase phase) {
  phase_ = phase;
  error_ = std::move(why);
  return Error{error_};
}

Status ClientSession::onStreamBytes(std::span<const std::uint8_t> bytes, double now) {
  events_.clear();
  if (phase_ == SessionPhase::Rejected || phase_ == SessionPhase::Failed) return Error{error_};
  if (!connectedPhase()) return Status::success();  // no connection these bytes could be from
  stats_.tcpBytes += bytes.size();
  lastHeard_ = now;
  while (!bytes.empty()) {
    if (frame_.size() < kFramePrefixBytes) {
      const std::size_t take = std::min(kFramePrefixBytes - frame_.size(), bytes.size());
      frame_.insert(frame_.end(), bytes.begin(), bytes.begin() + std::ptrdiff_t(take));
      bytes = bytes.subspan(take);
      if (frame_.size() < kFramePrefixBytes) break;
      // Refused on the prefix alone: a frame over the limit is never read.
      auto size = frameSize(frame_, kMaxSessionMessageBytes);
      if (!size) return fail("bad frame from the server: " + size.error().message);
      frameBytes_ = *size;
    }
    const std::size_t take = std::min(frameBytes_ - frame_.size(), bytes.size());
    frame_.insert(frame_.end(), bytes.begin(), bytes.begin() + std::ptrdiff_t(take));
    bytes = bytes.subspan(take);
    if (frame_.size() < frameBytes_) break;
    Status handled = onFrame(frame_, now);
    frame_.clear();
    frameBytes_ = 0;
    if (!handled) return handled;
  }
  return Status::success();
}

Status ClientSession::onFrame(std::span<const std::uint8_t> frame, double now) {
  switch (classifyFrame(frame)) {
    case FrameKind::Datagram:
      ++stats_.tcpDatagrams;
      (void)handleDatagram(datagramOfFrame(frame), now);
      return Status::success();
    case FrameKind::SessionMessage: {
      auto message = decodeMessage(frame);
      if (!message) return fail("bad message from the server: " + message.error().message);
      return onMessage(*message, now);
    }
    case FrameKind::Unknown:
      break;
  }
  return fail("unknown frame from the server (neither a session message nor a datagram)");
}

Status ClientSession::onMessage(SessionMessage& message, double now) {
  const std::string name = sessionMessageName(message);
  if (std::holds_alternative<HelloMsg>(message) || std::holds_alternative<ViewerPoseMsg>(message) ||
      std::holds_alternative<AckMsg>(message) ||
      std::holds_alternative<RepairRequestMsg>(message) ||
      std::holds_alternative<ResumeMsg>(message) || std::holds_alternative<EditMsg>(message))
    return fail(name + " from the server: only a client sends it");
  if (const auto* reject = std::get_if<RejectMsg>(&message)) {
    ++stats_.rejects;
    // Quoted and cut: the reason is the server's text, and ends up in the client's log.
    return fail("rejected: " + quoteUntrusted(reject->reason, kMaxQuotedReasonBytes),
                SessionPhase::Rejected);
  }
  if (const auto* welcome = std::get_if<WelcomeMsg>(&message)) {
    if (phase_ != SessionPhase::AwaitingWelcome) return fail("a second Welcome");
    Status version = checkServerVersion(welcome->protocolVersion);
    if (!version) return fail(version.error().message);
    sessionId_ = welcome->sessionId;
    spokenVersion_ = welcome->protocolVersion;
    phase_ = SessionPhase::AwaitingLayout;
    events_.push_back(SessionEvent{SessionEvent::Kind::Welcomed, {}, {}});
    if (datagramKey_) {
      opener_.emplace(*datagramKey_, sessionId_);
      auto early = std::move(earlySealed_);
      earlySealed_.clear();
      for (const auto& [d, port] : early) (void)openDatagram(d, now, port);
    }
    return Status::success();
  }
  // The rest belongs to a session: the Welcome comes first.
  if (phase_ == SessionPhase::AwaitingWelcome) return fail(name + " before Welcome");
  if (const auto* info = std::get_if<SessionInfoMsg>(&message)) return onSessionInfo(*info, now);
  if (const auto* report = std::get_if<StreamReportMsg>(&message)) {
    if (phase_ != SessionPhase::Streaming) return fail("StreamReport before SessionInfo");
    report_ = *report;
    reportAt_ = now;
    receiver_->announceFieldVersion(report->fieldVersion);
    ++stats_.streamReports;
    events_.push_back(SessionEvent{SessionEvent::Kind::StreamReport, {}, {}});
    return Status::success();
  }
  if (auto* result = std::get_if<EditResultMsg>(&message)) {
    if (phase_ != SessionPhase::Streaming) return fail("EditResult before SessionInfo");
    SessionEvent e{SessionEvent::Kind::EditResult, {}, {}};
    e.edit = std::move(*result);
    events_.push_back(std::move(e));
    return Status::success();
  }
  auto& state = std::get<SceneStateMsg>(message);
  clock_.update(state.animationTime, now);
  if (receiver_) {
    receiver_->announceFieldVersion(state.fieldVersion);
    // Cascades that follow the viewers: the mirror moves with them (its bricks' layout stamps
    // say which slots stay valid).
    if (Status moved = receiver_->moveCascades(state.cascadePlaces); !moved)
      return fail(moved.error().message);
  }
  // The newest state with edits in force: the scene, until a state without them comes.
  if (state.editVersion > 0) {
    edited_ = state;
  } else {
    edited_.reset();
  }
  events_.push_back(SessionEvent{SessionEvent::Kind::SceneState, std::move(state), {}});
  return Status::success();
}

Status ClientSession::onSessionInfo(const SessionInfoMsg& info, double now) {
  if (phase_ == SessionPhase::Streaming) return fail("a second SessionInfo");
  // Checked before anything is laid out: a hostile or broken server could otherwise make this
  // client allocate tens of GiB (mirrorField accepts up to 4M probe slots).
  const std::uint64_t needed = mirrorMemoryBytes(info);
  if (needed > options_.maxMirrorBytes) {
    const auto mib = [](std::uint64_t b) { return std::to_string((b + (1u << 20) - 1) >> 20); };
    return fail("session info: the server's field layout (" + std::to_string(info.cascades.size()) +
                " cascades) needs about " + mib(needed) +
                " MiB of mirror memory, over this client's cap of " + mib(options_.maxMirrorBytes) +
                " MiB (maxMirrorBytes)");
  }
  auto created = StreamReceiver::create(info, sessionId_, options_.receiver);
  if (!created) return fail(created.error().message);  // mirrorField names "session info"
  receiver_.emplace(std::move(created).value());
  info_ = info;
  resume();
  const Field& layout = receiver_->field();
  held_.assign(std::size_t(layout.cascadeCount()), {});
  changed_.assign(std::size_t(layout.cascadeCount()), {});
  bricksTotal_ = bricksHeld_ = 0;
  for (int k = 0; k < layout.cascadeCount(); ++k) {
    held_[k].assign(layout.brickVersions[k].size(), false);
    changed_[k].assign(layout.brickVersions[k].size(), false);
    bricksTotal_ += int(layout.brickVersions[k].size());
    for (std::size_t b = 0; b < layout.brickVersions[k].size(); ++b) {
      held_[k][b] = receiver_->brickVersion(k, int(b)) != 0;  // resumed
      bricksHeld_ += held_[k][b];
    }
  }
  changedList_.clear();
  lastApplied_ = 0;
  synced_ = bricksHeld_ == bricksTotal_;
  syncSeconds_ = synced_ ? now - connectStartedAt_ : -1;
  lastPoseAt_ = -1e30;  // the server learns the viewer at once
  phase_ = SessionPhase::Streaming;
  ++stats_.sessions;
  events_.push_back(SessionEvent{SessionEvent::Kind::Layout, {}, {}});
  auto early = std::move(early_);
  early_.clear();
  for (const auto& [d, port] : early) (void)handleDatagram(d, now, port);
  return Status::success();
}

void ClientSession::resume() {
  std::optional<StreamReceiver> kept = std::move(keptReceiver_);
  keptReceiver_.reset();
  // A version 7 server whose Hello named an epoch waits for the Resume: it always gets one,
  // empty (holding nothing) where the field is another.
  if (spokenVersion_ < kResumeVersion || heldEpoch_ == 0) return;
  resumeFrame_ = encodeMessage(ResumeMsg{});  // nothing
  if (!kept || keptInfo_.fieldEpoch != info_.fieldEpoch || keptInfo_.sceneHash != info_.sceneHash ||
      !receiver_->adoptHeld(std::move(*kept)))
    return;
  std::vector<std::uint8_t> claim =
      encodeMessage(resumeMessage(info_.sceneHash, info_.fieldEpoch, receiver_->heldBricks()));
  if (claim.size() > kMaxResumeFrameBytes) {
    // Only a field of tens of thousands of bricks at scattered versions and precisions comes
    // near this, which the queue to the server could not take: start from nothing instead.
    auto fresh = StreamReceiver::create(info_, sessionId_, options_.receiver);
    if (fresh) receiver_.emplace(std::move(fresh).value());
    return;
  }
  resumeFrame_ = std::move(claim);
  ++stats_.resumes;
}

Status ClientSession::onDatagram(std::span<const std::uint8_t> bytes, double now,
                                 DatagramSource source) {
  events_.clear();
  ++stats_.udpDatagrams;
  stats_.udpBytes += bytes.size();
  if (!connectedPhase()) return Status::success();  // from no session of this client
  if (!source.serverAddress || (serverUdpPort_ != 0 && source.port != serverUdpPort_)) {
    ++stats_.foreignDatagrams;
    return Error{"datagram from another source than the server"};
  }
  if (datagramKey_) {
    if (!opener_) {
      // Before the Welcome names the session: kept sealed until it does.
      if (earlySealed_.size() < kMaxEarlyDatagrams) {
        earlySealed_.emplace_back(std::vector<std::uint8_t>(bytes.begin(), bytes.end()),
                                  source.port);
      } else {
        ++stats_.droppedEarlyDatagrams;
      }
      return Status::success();
    }
    return openDatagram(bytes, now, source.port);
  }
  Status status = handleDatagram(bytes, now, source.port);
  if (status && phase_ == SessionPhase::Streaming) lastHeard_ = now;
  return status;
}

Status ClientSession::openDatagram(std::span<const std::uint8_t> sealed, double now,
                                   std::uint16_t port) {
  auto plain = opener_->open(sealed);
  if (!plain) {
    ++stats_.unsealedRefused;
    Status refused = Error{"sealed datagram refused: " + plain.error().message};
    events_.push_back(SessionEvent{SessionEvent::Kind::Datagram, {}, refused});
    return refused;
  }
  // Only an authentic datagram of this session shows that the server is alive, and names the
  // port the server sends from.
  lastHeard_ = now;
  if (serverUdpPort_ == 0) serverUdpPort_ = port;
  return handleDatagram(*plain, now);
}

Status ClientSession::handleDatagram(std::span<const std::uint8_t> bytes, double now,
                                     std::uint16_t port) {
  if (phase_ == SessionPhase::AwaitingWelcome || phase_ == SessionPhase::AwaitingLayout) {
    // Before SessionInfo: kept for when the receiver exists.
    if (early_.size() < kMaxEarlyDatagrams) {
      early_.emplace_back(std::vector<std::uint8_t>(bytes.begin(), bytes.end()), port);
    } else {
      ++stats_.droppedEarlyDatagrams;
    }
    return Status::success();
  }
  if (phase_ != SessionPhase::Streaming) return Status::success();
  Status status = receiver_->onDatagram(bytes, now);
  if (!status) ++stats_.badDatagrams;
  // An unsealed datagram names the server's port once the receiver took it.
  if (status && port != 0 && serverUdpPort_ == 0) serverUdpPort_ = port;
  collectChanges(now);
  events_.push_back(SessionEvent{SessionEvent::Kind::Datagram, {}, status});
  return status;
}

void ClientSession::collectChanges(double now) {
  const std::uint64_t applied = receiver_->stats().applied;
  if (applied == lastApplied_) return;  // the common case under load: nothing to scan
  lastApplied_ = applied;
  for (auto [k, b] : receiver_->takeChangedBricks()) {
    if (!held_[k][b]) {
      held_[k][b] = true;
      ++bricksHeld_;
    }
    if (!changed_[k][b]) {
      changed_[k][b] = true;
      changedList_.emplace_back(k, b);
    }
  }
  if (!synced_ && bricksHeld_ == bricksTotal_) {
    synced_ = true;
    syncSeconds_ = now - connectStartedAt_;
  }
}

std::vector<std::pair<int, int>> ClientSession::takeChangedBricks() {
  std::vector<std::pair<int, int>> out;
  out.swap(changedList_);
  for (auto [k, b] : out) changed_[k][b] = false;
  return out;
}

Result<std::vector<std::vector<std::uint8_t>>> ClientSession::poll(double now) {
  std::vector<std::vector<std::uint8_t>> out;
  if (phase_ == SessionPhase::Idle || phase_ == SessionPhase::Rejected ||
      phase_ == SessionPhase::Failed)
    return out;
  if (phase_ != SessionPhase::Streaming && now - connectStartedAt_ > options_.connectTimeout)
    return fail("no session within " + std::to_string(options_.connectTimeout) + " s");
  if (phase_ != SessionPhase::Connecting && now - lastHeard_ > options_.silenceTimeout)
    return fail("server silent for " + std::to_string(options_.silenceTimeout) + " s");
  if (phase_ != SessionPhase::Streaming) return out;
  out = receiver_->poll(now);
  if (!uplink_) startUplink();
  if (uplink_) {
    // Acks and repair requests (all the receiver sends) as datagrams, where they fit one.
    std::erase_if(out, [&](const std::vector<std::uint8_t>& frame) {
      if (frame.size() > kMaxUplinkFrameBytes) {
        ++stats_.uplinkTooLarge;
        return false;
      }
      auto datagram = uplink_->wrap(frame);
      if (!datagram) return false;  // the counter is used up: the stream carries it
      if (uplinkOut_.size() >= kMaxQueuedUplinkDatagrams) uplinkOut_.erase(uplinkOut_.begin());
      uplinkOut_.push_back(std::move(datagram).value());
      ++stats_.uplinkDatagrams;
      return true;
    });
  }
  // The Resume before anything else on the stream (the acks of the held versions follow it).
  if (!resumeFrame_.empty()) out.insert(out.begin(), std::move(resumeFrame_));
  resumeFrame_.clear();
  for (auto& edit : editsOut_) out.push_back(std::move(edit));
  editsOut_.clear();
  if (viewer_ && poseDue(now)) {
    ViewerPoseMsg pose = *viewer_;
    pose.time = clock_.at(now).value_or(0.0);
    out.push_back(encodeMessage(pose));
    lastPoseAt_ = now;
  }
  return out;
}

Status ClientSession::sendEdit(const EditMsg& edit) {
  if (phase_ != SessionPhase::Streaming) return Error{"no session to send the edit in"};
  if (spokenVersion_ < kEditsVersion)
    return Error{"the server speaks protocol version " + std::to_string(spokenVersion_) +
                 ", which takes no edits (version " + std::to_string(kEditsVersion) + ")"};
  if (editsOut_.size() >= kMaxQueuedEdits)
    return Error{std::to_string(kMaxQueuedEdits) + " edits are waiting already"};
  editsOut_.push_back(encodeMessage(edit));
  return Status::success();
}

void ClientSession::startUplink() {
  // The server named a port (a version 6 server, a session with UDP), and an authentic
  // datagram came over UDP: the path works, at least towards this client.
  if (!options_.uplinkDatagrams || phase_ != SessionPhase::Streaming ||
      spokenVersion_ < kUplinkDatagramsVersion || info_.uplinkPort == 0 || serverUdpPort_ == 0 ||
      datagramKey_.has_value() != uplinkKey_.has_value())
    return;
  uplink_.emplace(uplinkKey_, sessionId_);
  receiver_->setAckRepeats(kUplinkAckRepeats);
}

std::vector<std::vector<std::uint8_t>> ClientSession::takeUplinkDatagrams() {
  std::vector<std::vector<std::uint8_t>> out;
  out.swap(uplinkOut_);
  return out;
}

void ClientSession::setViewer(glm::vec3 position, glm::quat orientation) {
  ViewerPoseMsg pose;
  pose.position = position;
  pose.orientation = orientation;
  viewer_ = pose;
}

bool ClientSession::poseDue(double now) const {
  return phase_ == SessionPhase::Streaming && now - lastPoseAt_ >= options_.poseInterval;
}

}  // namespace pc
