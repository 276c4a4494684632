#include "net_session.h"

#include <algorithm>
#include <chrono>
#include <variant>

#include "common/log.h"

namespace pc {

namespace {

// Before a client has shown a valid token it may send one small Hello, nothing bigger: an
// unauthenticated peer never makes the server allocate the full message limit.
constexpr std::size_t kMaxHelloFrameBytes = 4096;
// The most bytes of queued frames one write takes together.
constexpr std::size_t kWriteBatchBytes = 64u << 10;
// A receive buffer grown past this by one large message (a full ack) is given back after it.
constexpr std::size_t kKeptFrameCapacity = 64u << 10;
// A client's name is kept (and logged, quoted) up to this many bytes.
constexpr std::size_t kMaxClientNameBytes = 64;

std::uint32_t readLittleEndian32(const std::array<std::uint8_t, kFramePrefixBytes>& b) {
  return std::uint32_t(b[0]) | std::uint32_t(b[1]) << 8 | std::uint32_t(b[2]) << 16 |
         std::uint32_t(b[3]) << 24;
}

// A client that closes its TCP connection without TLS's close_notify ends the stream
// "truncated": for a session (whose messages are framed) that is an ordinary close.
std::string readFailure(boost::system::error_code ec) {
  if (ec == asio::error::eof || ec == net::ssl::error::stream_truncated)
    return "connection closed by the client";
  return "read failed: " + ec.message();
}

// Causes that a client brings on itself: logged as warnings.
bool misbehaviour(DisconnectCause c) {
  switch (c) {
    case DisconnectCause::ClientClosed:
    case DisconnectCause::Rejected:
    case DisconnectCause::Shutdown:
      return false;
    default:
      return true;
  }
}

}  // namespace

Session::Session(NetServer::Impl& server, net::SessionStream stream, std::uint32_t id)
    : server_(server), stream_(std::move(stream)), id_(id) {
  boost::system::error_code ec;
  auto remote = stream_.socket().remote_endpoint(ec);
  peer_ =
      ec ? std::string("?") : remote.address().to_string() + ":" + std::to_string(remote.port());
  if (!ec) peerAddress_ = remote.address();
  acceptedAt_ = lastHeard_ = steadySeconds();
  stream_.socket().set_option(tcp::no_delay(true), ec);
  // Flood limits; before the Hello the prefix check allows one small frame anyway.
  messageBucket_.init(server_.options.maxMessagesPerSecond, server_.options.maxMessagesPerSecond,
                      acceptedAt_);
  byteBucket_.init(server_.maxReceiveBytesPerSecond, server_.maxReceiveBytesPerSecond, acceptedAt_);
}

void Session::close(DisconnectCause cause, const std::string& detail) {
  if (closed_) return;
  closed_ = true;
  logEvent(misbehaviour(cause) ? LogLevel::Warn : LogLevel::Info, "client disconnected",
           {{"session", id_},
            {"peer", peer_},
            {"name", escapeUntrusted(name_, kMaxClientNameBytes)},
            {"cause", causeName(cause)},
            {"detail", detail},
            {"seconds", steadySeconds() - acceptedAt_}});
  stream_.close();
  server_.hub.removeViewer(id_);
  server_.remove(id_, cause);
  // After remove(): it counts this session as established while sender_ is set.
  auto lock = server_.hub.lock();
  sender_.reset();
}

void Session::refuse(DisconnectCause cause, const std::string& detail) {
  if (closed_) return;
  ++server_.totals.rejectedMessages[std::size_t(cause)];
  close(cause, detail);
}

void Session::pollLocked(double now, std::uint64_t sceneSerial, const SharedBytes& sceneFrame,
                         std::vector<Bytes>& datagrams, SharedBytes& scene) {
  if (closed_ || !sender_) return;
  if (sceneSerial != sceneSerialSent_ && sceneFrame) {
    sceneSerialSent_ = sceneSerial;
    scene = sceneFrame;
  }
  // Over TCP the sender is polled only while the queue is short: what it holds back stays
  // one entry per brick (the newest version), never a growing backlog here.
  if (!udpTarget_ && queuedBytes_ >= server_.options.tcpDatagramQueueBytes) {
    ++tcpQueueFullPolls_;
    return;
  }
  datagrams = sender_->poll(now);
  // Versions published before the client joined are its initial sync, not latency (as the
  // load generator counts it).
  for (const std::uint64_t version : sender_->firstSends()) {
    if (version <= joinedAtVersion_) continue;
    if (auto published = server_.hub.publishTimeOf(version))
      sentPublishTimes_.push_back(*published);
  }
  if (reports_ && now - lastReportAt_ >= kStreamReportInterval) {
    // What the sender sees of this client, for the client's own figures; computed here, where
    // the publisher may be read, and written by send().
    lastReportAt_ = now;
    const StreamReportMsg r = sender_->report(now);
    report_ = encodeMessage(r);
    lastReport_ = r;
  }
  pendingBricks_ = sender_->pendingBricks();
  resends_ = sender_->stats().resends;
  repairedFragments_ = sender_->stats().repairedFragments;
}

void Session::sealDatagrams(double now, std::vector<Bytes>& datagrams, std::vector<UdpOut>& out) {
  if (closed_ || !sealFailure_.empty() || !udpTarget_) return;
  for (Bytes& d : datagrams) {
    // Sealed with this session's key: nobody else can read them, nor write into this session.
    if (sealer_) {
      Bytes sealed;
      sealed.reserve(d.size() + kSealOverheadBytes);
      if (Status s = sealer_->seal(d, sealed); !s) {
        sealFailure_ = "datagram keys used up: " + s.error().message;
        break;
      }
      d = std::move(sealed);
    }
    out.push_back({this, *udpTarget_, std::move(d), now});
  }
  datagrams.clear();
}

void Session::send(double now, std::vector<Bytes> datagrams, const SharedBytes& scene) {
  if (closed_) return;
  if (!sealFailure_.empty()) return close(DisconnectCause::Shutdown, sealFailure_);
  if (scene) enqueue(scene);
  if (!report_.empty()) enqueue(share(std::move(report_)));
  report_.clear();
  if (udpTarget_) {
    // Sent with every other session's datagrams of this poll (Impl::flushUdp).
    sealDatagrams(now, datagrams, server_.udpBatch);
    if (!sealFailure_.empty()) return close(DisconnectCause::Shutdown, sealFailure_);
  }
  for (Bytes& d : datagrams) {
    if (closed_) return;
    enqueue(share(datagramFrame(d)));
    ++datagrams_;
  }
  checkTimeouts(now);
}

void Session::observeSent(double now, Histogram& latency) {
  for (const double published : sentPublishTimes_) latency.observe(std::max(0.0, now - published));
  sentPublishTimes_.clear();
}

void Session::udpSent(std::size_t bytes, bool ok) {
  if (!ok) {
    ++udpDropped_;
    return;
  }
  bytesSent_ += bytes;
  ++datagrams_;
}

void Session::checkTimeouts(double now) {
  if (closed_) return;
  if (!sender_ && !closeAfterFlush_ && now - acceptedAt_ > server_.options.helloTimeout) {
    close(DisconnectCause::HelloTimeout,
          "no Hello within " + std::to_string(server_.options.helloTimeout) + " s");
  } else if (writing_ && now - writeStartedAt_ > server_.options.writeStallSeconds) {
    close(DisconnectCause::NotReading,
          "no write progress for " + std::to_string(server_.options.writeStallSeconds) + " s");
  } else if (sender_ && now - lastHeard_ > server_.options.silenceTimeout) {
    close(DisconnectCause::Silent,
          "no message for " + std::to_string(server_.options.silenceTimeout) + " s");
  }
}

NetClientInfo Session::info(double now) const {
  NetClientInfo c;
  c.sessionId = id_;
  c.name = name_;
  c.peer = peer_;
  c.udp = udpTarget_.has_value();
  c.connectedSeconds = now - acceptedAt_;
  c.bytesSent = bytesSent_;
  c.datagrams = datagrams_;
  c.udpDropped = udpDropped_;
  c.bytesReceived = bytesReceived_;
  c.messagesReceived = messagesReceived_;
  c.pendingBricks = pendingBricks_;
  c.resends = resends_;
  c.repairedFragments = repairedFragments_;
  c.acksTcp = acksTcp_;
  c.acksUdp = acksUdp_;
  c.repairsTcp = repairsTcp_;
  c.repairsUdp = repairsUdp_;
  c.report = lastReport_;
  return c;
}

void Session::start() {
  auto self = shared_from_this();
  stream_.asyncHandshake(net::ssl::stream_base::server,
                         [self](boost::system::error_code ec) { self->onHandshake(ec); });
}

void Session::onHandshake(boost::system::error_code ec) {
  if (closed_) return;
  if (ec) {
    ++server_.totals.rejectedMessages[std::size_t(DisconnectCause::TlsHandshake)];
    return close(DisconnectCause::TlsHandshake, ec.message());
  }
  if (stream_.tls()) {
    auto secret = stream_.datagramSecret();
    if (!secret) return close(DisconnectCause::TlsHandshake, secret.error().message);
    const DatagramKeys keys = deriveDatagramKeys(*secret);
    sealer_.emplace(keys.serverToClient, id_);
    uplinkKey_ = keys.clientToServer;
  }
  readMore();
}

// Reads whatever the stream holds (up to the input buffer) and handles every whole frame in
// it: one read per batch of messages, not two per message. Over TLS each read is a pass
// through the SSL engine, and a client sends about 60 small messages a second.
void Session::readMore() {
  auto self = shared_from_this();
  stream_.async_read_some(asio::buffer(input_), [self](boost::system::error_code ec,
                                                       std::size_t n) { self->onRead(ec, n); });
}

void Session::onRead(boost::system::error_code ec, std::size_t n) {
  if (closed_) return;
  if (ec) return close(DisconnectCause::ClientClosed, readFailure(ec));
  std::span<const std::uint8_t> bytes(input_.data(), n);
  while (!bytes.empty()) {
    if (frameBytes_ == 0) {
      const std::size_t take = std::min(kFramePrefixBytes - frame_.size(), bytes.size());
      frame_.insert(frame_.end(), bytes.begin(), bytes.begin() + std::ptrdiff_t(take));
      bytes = bytes.subspan(take);
      if (frame_.size() < kFramePrefixBytes) break;
      if (!acceptPrefix()) return;
    }
    const std::size_t take = std::min(frameBytes_ - frame_.size(), bytes.size());
    frame_.insert(frame_.end(), bytes.begin(), bytes.begin() + std::ptrdiff_t(take));
    bytes = bytes.subspan(take);
    if (frame_.size() < frameBytes_) break;
    if (!onFrame()) return;
    frameBytes_ = 0;
    frame_.clear();
    if (frame_.capacity() > kKeptFrameCapacity) Bytes().swap(frame_);
  }
  readMore();
}

bool Session::acceptPrefix() {
  // Every check on the prefix alone, before the frame's buffer grows past it.
  const std::size_t limit = sender_ ? server_.maxMessageBytes : kMaxHelloFrameBytes;
  std::array<std::uint8_t, kFramePrefixBytes> prefix{};
  std::copy_n(frame_.begin(), kFramePrefixBytes, prefix.begin());
  const std::size_t announced = readLittleEndian32(prefix) + kFramePrefixBytes;
  if (announced > limit) {
    refuse(DisconnectCause::Oversized, "frame of " + std::to_string(announced) +
                                           " bytes announced, the cap is " + std::to_string(limit) +
                                           (sender_ ? "" : " before a Hello"));
    return false;
  }
  auto size = frameSize(prefix, limit);
  if (!size) {
    refuse(DisconnectCause::Malformed, "bad frame: " + size.error().message);
    return false;
  }
  if (!withinFloodLimits(*size, steadySeconds())) return false;
  frameBytes_ = *size;
  frame_.reserve(*size);
  return true;
}

bool Session::withinFloodLimits(std::size_t bytes, double now) {
  if (!messageBucket_.take(1, now)) {
    refuse(DisconnectCause::Flood, "more than " +
                                       std::to_string(server_.options.maxMessagesPerSecond) +
                                       " messages per second");
    return false;
  }
  if (!byteBucket_.take(double(bytes), now)) {
    refuse(DisconnectCause::Flood,
           "more than " + std::to_string(server_.maxReceiveBytesPerSecond) + " bytes per second");
    return false;
  }
  return true;
}

std::optional<UplinkDrop> Session::onUplink(std::span<const std::uint8_t> bytes,
                                            const udp::endpoint& from, double now) {
  if (closed_ || !uplink_) return UplinkDrop::UnknownSession;
  // The sealed form is the session's wherever it comes from (a client behind a NAT may change
  // ports); nothing authenticates the plain form but the address it comes from. Either way
  // datagrams still go only where the Hello said.
  if (!uplink_->sealed() && from.address() != peerAddress_) return UplinkDrop::WrongSender;
  UplinkDrop cause = UplinkDrop::Malformed;
  auto frame = uplink_->open(bytes, cause);
  if (!frame) return cause;
  // The client's own from here: held to the same rules as on the stream.
  bytesReceived_ += frame->size();
  ++messagesReceived_;
  lastHeard_ = now;
  if (!withinFloodLimits(frame->size(), now)) return std::nullopt;
  auto message = decodeMessage(*frame);
  if (!message) {
    refuse(DisconnectCause::Malformed, "datagram: " + message.error().message);
    return std::nullopt;
  }
  if (!std::holds_alternative<AckMsg>(*message) &&
      !std::holds_alternative<RepairRequestMsg>(*message)) {
    refuse(DisconnectCause::Protocol, std::string(sessionMessageName(*message)) +
                                          " as a datagram: only acks and repair requests");
    return std::nullopt;
  }
  (void)handle(*message, true);
  return std::nullopt;
}

bool Session::onFrame() {
  bytesReceived_ += frame_.size();
  ++messagesReceived_;
  lastHeard_ = steadySeconds();
  switch (classifyFrame(frame_)) {
    case FrameKind::SessionMessage:
      break;
    case FrameKind::Datagram:
      refuse(DisconnectCause::WrongDirection, "a datagram frame: only the server sends datagrams");
      return false;
    case FrameKind::Unknown:
      refuse(DisconnectCause::Malformed, "not a session message frame");
      return false;
  }
  auto message = decodeMessage(frame_);
  if (!message) {
    refuse(DisconnectCause::Malformed, message.error().message);
    return false;
  }
  return handle(*message) && !closed_;
}

bool Session::handle(const SessionMessage& message, bool overUdp) {
  if (!sender_) {
    const HelloMsg* hello = std::get_if<HelloMsg>(&message);
    if (!hello) {
      refuse(DisconnectCause::Protocol, std::string("expected Hello as the first message, got ") +
                                            sessionMessageName(message));
      return false;
    }
    return onHello(*hello);
  }
  if (std::holds_alternative<HelloMsg>(message)) {
    refuse(DisconnectCause::Protocol, "a second Hello");
    return false;
  }
  if (std::holds_alternative<WelcomeMsg>(message) || std::holds_alternative<RejectMsg>(message) ||
      std::holds_alternative<SessionInfoMsg>(message) ||
      std::holds_alternative<SceneStateMsg>(message) ||
      std::holds_alternative<StreamReportMsg>(message) ||
      std::holds_alternative<EditResultMsg>(message)) {
    refuse(DisconnectCause::WrongDirection,
           std::string(sessionMessageName(message)) + " from a client: only the server sends it");
    return false;
  }
  if (auto invalid = checkSize(message)) {
    refuse(DisconnectCause::Invalid, *invalid);
    return false;
  }
  if (const auto* edit = std::get_if<EditMsg>(&message)) {
    if (overUdp) {
      refuse(DisconnectCause::Protocol, "Edit as a datagram: only acks and repair requests");
      return false;
    }
    onEdit(*edit);
    return !closed_;
  }
  if (const auto* pose = std::get_if<ViewerPoseMsg>(&message)) setViewer(*pose);
  Status status;
  {
    auto lock = server_.hub.lock();
    status = sender_->onMessage(message, steadySeconds());
  }
  if (!status) {
    refuse(DisconnectCause::Invalid, status.error().message);
    return false;
  }
  if (std::holds_alternative<ResumeMsg>(message)) {
    // Counted once, as the sender judged the claim.
    const SenderStats& st = sender_->stats();
    server_.totals.resumes += st.resumes;
    server_.totals.resumeMismatches += st.resumeMismatches;
    server_.totals.resumedBricks += st.resumedBricks;
    server_.totals.resumeRefusedBricks += st.resumeRefusedBricks;
  }
  if (std::holds_alternative<AckMsg>(message)) ++(overUdp ? acksUdp_ : acksTcp_);
  if (std::holds_alternative<RepairRequestMsg>(message)) ++(overUdp ? repairsUdp_ : repairsTcp_);
  return true;
}

std::optional<std::string> Session::checkSize(const SessionMessage& message) const {
  const std::uint64_t bricks = server_.fieldBricks;
  if (const auto* ack = std::get_if<AckMsg>(&message)) {
    std::uint64_t covered = 0;
    for (const AckRange& r : ack->ranges) covered += r.count;
    if (ack->ranges.size() > bricks || covered > bricks) {
      return "ack with " + std::to_string(ack->ranges.size()) + " ranges covering " +
             std::to_string(covered) + " bricks; the field has " + std::to_string(bricks);
    }
  } else if (const auto* repair = std::get_if<RepairRequestMsg>(&message)) {
    if (repair->bricks.size() > bricks) {
      return "repair request naming " + std::to_string(repair->bricks.size()) +
             " bricks; the field has " + std::to_string(bricks);
    }
  } else if (const auto* resume = std::get_if<ResumeMsg>(&message)) {
    if (resume->brickCount > bricks) {
      return "resume claiming " + std::to_string(resume->brickCount) + " bricks; the field has " +
             std::to_string(bricks);
    }
  }
  return std::nullopt;
}

bool Session::followsViewers() const {
  auto lock = server_.hub.sharedLock();
  for (const gpu::CascadeDesc& c : server_.hub.publisher().sessionInfo().cascades)
    if (c.follows != 0) return true;
  return false;
}

bool Session::onHello(const HelloMsg& hello) {
  name_ = hello.clientName.substr(0, kMaxClientNameBytes);
  const std::int64_t nowUnix = unixSeconds();
  HelloVerdict verdict = checkHello(hello, server_.verifier, server_.options.sceneName, nowUnix);
  std::optional<RejectMsg> reject = std::move(verdict.reject);
  RejectCause cause = verdict.versionMismatch ? RejectCause::Version : RejectCause::Auth;
  // The per-client cap counts tokens: one token holder cannot take every place.
  const std::string tokenKey = tokenIdHex(verdict.claims.id);
  if (!reject && hello.protocolVersion < kFirstMovingCascadesVersion && followsViewers()) {
    // Its bricks carry layout stamps an older client cannot read, and it would not move its
    // copy of the field with the cascades.
    reject = RejectMsg{kProtocolVersion,
                       "this server's cascades follow the viewers: protocol version " +
                           std::to_string(kFirstMovingCascadesVersion) + " or later needed"};
    cause = RejectCause::Version;
  }
  if (!reject && server_.established >= server_.options.maxClients) {
    reject = RejectMsg{kProtocolVersion,
                       "server full: cap " + std::to_string(server_.options.maxClients)};
    cause = RejectCause::ServerFull;
  } else if (!reject) {
    if (auto why = server_.addressLimits.admitClient(tokenKey)) {
      reject = RejectMsg{kProtocolVersion, "client limit: " + *why};
      cause = RejectCause::ClientLimit;
    } else if (auto whyAddress = server_.addressLimits.promote(addressKey_)) {
      // Over its address's session cap: the client hears why, so that it backs off rather
      // than reading a bare close as a fault.
      server_.addressLimits.releaseClient(tokenKey);
      reject = RejectMsg{kProtocolVersion, "address limit: " + *whyAddress};
      cause = RejectCause::AddressLimit;
    }
  }
  if (reject) {
    logEvent(LogLevel::Warn, "client rejected",
             {{"session", id_},
              {"peer", peer_},
              {"name", escapeUntrusted(name_, kMaxClientNameBytes)},
              {"cause", causeName(cause)},
              {"reason", reject->reason}});
    ++server_.totals.rejected;
    ++server_.totals.rejects[std::size_t(cause)];
    if (verdict.tokenError) ++server_.totals.tokenRejects[std::size_t(*verdict.tokenError)];
    sendReject(std::move(*reject));
    return false;
  }
  // The identity the per-client cap counts; released by the server when the session ends.
  clientKey_ = tokenKey;
  // The token names the client: what is logged and counted is the token's name and id, not
  // what the client chose to call itself.
  claims_ = std::move(verdict.claims);
  name_ = claims_.client;
  viewerWeight_ = int(claims_.weight);  // what the token allows this client's viewer
  const bool useUdp = !server_.options.tcpOnly && hello.wantsUdp && hello.udpPort != 0;
  if (useUdp) {
    boost::system::error_code ec;
    // Datagrams go only to the address the session came from: a client cannot aim the
    // server at a third party.
    udpTarget_ = udp::endpoint(stream_.socket().remote_endpoint(ec).address(), hello.udpPort);
    if (ec) {
      close(DisconnectCause::ClientClosed, "no remote address: " + ec.message());
      return false;
    }
  }
  SessionInfoMsg info;
  SharedBytes scene;
  {
    auto lock = server_.hub.lock();
    info = server_.hub.publisher().sessionInfo();
    // Congestion control needs the client's arrival reports, which version 3 sends.
    SenderOptions senderOptions = server_.options.sender;
    reports_ = hello.protocolVersion >= kCongestionControlVersion;
    senderOptions.congestionControl &= reports_;
    // Coarser precision levels only for clients that say which level they hold.
    if (hello.protocolVersion < kPrecisionLevelsVersion) senderOptions.maxPrecision = 0;
    sender_ = std::make_unique<StreamSender>(server_.hub.publisher(), id_, senderOptions,
                                             &server_.changeCache);
    // A client whose mirror holds this run's field says what of it in a Resume, which follows
    // the SessionInfo one round trip later: the sender waits for it rather than send bricks
    // the client holds.
    if (hello.protocolVersion >= kResumeVersion && hello.heldEpoch != 0 &&
        hello.heldEpoch == info.fieldEpoch)
      sender_->awaitResume(steadySeconds() + kResumeWaitSeconds);
    // Acks as datagrams from clients that send them, on sessions with a UDP path: the client
    // learns the port from the SessionInfo.
    if (useUdp && hello.protocolVersion >= kUplinkDatagramsVersion) {
      uplink_.emplace(uplinkKey_, id_);
      info.uplinkPort = server_.udpPortNumber;
    }
    scene = server_.hub.sceneFrame();
    sceneSerialSent_ = server_.hub.sceneSerial();
    joinedAtVersion_ = server_.hub.publisher().fieldVersion();
  }
  ++server_.established;
  ++server_.totals.sessions;
  logEvent(LogLevel::Info, "client joined",
           {{"session", id_},
            {"peer", peer_},
            {"name", escapeUntrusted(name_, kMaxClientNameBytes)},
            {"token", tokenIdHex(claims_.id)},
            {"role", std::string(tokenRoleName(claims_.role))},
            {"transport", useUdp ? "udp" : "tcp"},
            {"udp_port", useUdp ? int(hello.udpPort) : 0}});
  // The version both ends speak: an older client hears its own, which it accepts.
  const std::uint32_t spoken = std::min(kProtocolVersion, hello.protocolVersion);
  enqueue(share(encodeMessage(WelcomeMsg{spoken, id_})));
  enqueue(share(encodeMessage(info)));
  if (scene) enqueue(scene);
  return !closed_;
}

void Session::sendReject(RejectMsg reject) {
  // Nothing but the Reject goes out; the connection closes once it is written.
  closeAfterFlush_ = true;
  Bytes frame = encodeMessage(reject);
  while (frame.size() > bytesReceived_ && !reject.reason.empty()) {
    const std::size_t over = frame.size() - std::size_t(bytesReceived_);
    reject.reason.resize(reject.reason.size() - std::min(over, reject.reason.size()));
    frame = encodeMessage(reject);
  }
  if (frame.size() > bytesReceived_)
    return close(DisconnectCause::Rejected, "Hello too short for a Reject");
  enqueue(share(std::move(frame)));
}

void Session::onEdit(const EditMsg& edit) {
  EditResultMsg result;
  result.editId = edit.editId;
  result.target = edit.edit.target;
  const char* outcome = "applied";
  if (claims_.role != TokenRole::Editor) {
    // A viewer never changes the server's state; it hears why and keeps its session.
    result.reason = "edits need a connect token with the editor role; this one's is " +
                    std::string(tokenRoleName(claims_.role));
    outcome = "denied";
    ++server_.totals.editsDenied;
  } else if (!server_.options.edits) {
    result.reason = "this endpoint takes no edits (a relay): send them to the field server";
    outcome = "invalid";
    ++server_.totals.editsInvalid;
  } else if (auto applied = server_.options.edits(edit.edit); !applied) {
    result.reason = applied.error().message;
    outcome = "invalid";
    ++server_.totals.editsInvalid;
  } else {
    result.accepted = true;
    result.editVersion = applied->version;
    result.target = applied->target;
    ++server_.totals.editsApplied;
  }
  logEvent(result.accepted ? LogLevel::Info : LogLevel::Warn,
           result.accepted ? "edit applied" : "edit refused",
           {{"session", id_},
            {"name", escapeUntrusted(name_, kMaxClientNameBytes)},
            {"token", tokenIdHex(claims_.id)},
            {"role", std::string(tokenRoleName(claims_.role))},
            {"op", editOpName(edit.edit.op)},
            {"target", edit.edit.target},
            {"outcome", outcome},
            {"edit_version", result.editVersion},
            {"reason", result.reason}});
  enqueue(share(encodeMessage(result)));
}

void Session::setViewer(const ViewerPoseMsg& pose) {
  const glm::vec3 p = pose.position;
  const bool inside = glm::all(glm::greaterThanEqual(p, server_.viewerMin)) &&
                      glm::all(glm::lessThanEqual(p, server_.viewerMax));  // false for NaN
  if (!inside) return;  // ignored: the session's previous viewer stays
  // One viewer per session, of its weight: more sessions give one client more say only up to
  // the per-client and per-address session caps.
  server_.hub.setViewer(id_, p, viewerWeight_);
}

void Session::enqueue(SharedBytes bytes) {
  if (closed_) return;
  if (queuedBytes_ + bytes->size() > server_.options.maxWriteQueueBytes) {
    return close(
        DisconnectCause::NotReading,
        "write queue over " + std::to_string(server_.options.maxWriteQueueBytes) + " bytes");
  }
  queuedBytes_ += bytes->size();
  writes_.push_back({std::move(bytes), 1});
  frameQueuedAt_.push_back(steadySeconds());
  if (!writing_) writeNext();
}

void Session::writeNext() {
  writing_ = true;
  writeStartedAt_ = steadySeconds();
  // Frames queued while the last write was out leave together, up to kWriteBatchBytes: one
  // TLS record and one send for a scene state, a report and datagram frames, not one each.
  if (writes_.size() > 1 && writes_.front().bytes->size() < kWriteBatchBytes) {
    std::size_t total = 0;
    for (const Write& w : writes_) {
      if (total + w.bytes->size() > kWriteBatchBytes) break;
      total += w.bytes->size();
    }
    Bytes batch;
    batch.reserve(total);
    std::size_t frames = 0;
    while (!writes_.empty() && batch.size() + writes_.front().bytes->size() <= kWriteBatchBytes) {
      const Bytes& next = *writes_.front().bytes;
      batch.insert(batch.end(), next.begin(), next.end());
      frames += writes_.front().frames;
      writes_.pop_front();
    }
    // The same bytes and frames: queuedBytes_ and frameQueuedAt_ hold.
    writes_.push_front({share(std::move(batch)), frames});
  }
  auto self = shared_from_this();
  asio::async_write(
      stream_, asio::buffer(*writes_.front().bytes),
      [self](boost::system::error_code ec, std::size_t n) { self->onWritten(ec, n); });
}

void Session::onWritten(boost::system::error_code ec, std::size_t n) {
  if (closed_) return;
  if (ec) return close(DisconnectCause::ClientClosed, "write failed: " + ec.message());
  bytesSent_ += n;
  queuedBytes_ -= writes_.front().bytes->size();
  const double now = steadySeconds();
  for (std::size_t i = 0; i < writes_.front().frames && !frameQueuedAt_.empty(); ++i) {
    server_.totals.sendQueueDelay.observe(now - frameQueuedAt_.front());
    frameQueuedAt_.pop_front();
  }
  writes_.pop_front();
  if (!writes_.empty()) return writeNext();
  writing_ = false;
  if (closeAfterFlush_) close(DisconnectCause::Rejected, "Reject written");
}

}  // namespace pc
