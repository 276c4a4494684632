// Versions and size limits of the streaming protocol (PROTOCOL.md, "Streaming protocol").
// Every received buffer is checked against these before anything else reads it.
#pragma once

#include <cstddef>
#include <cstdint>

namespace pc {

// The protocol version this code speaks, and the oldest peer version it still serves. Bump by
// the rules in PROTOCOL.md ("Versioning of the streaming protocol").
// Version 2: brick codec format 2 (7 irradiance mantissa bits instead of 9); version 1 peers
// would misread its payloads, so they are not served.
// Version 3: acks report datagram arrivals (congestion control) and the server sends
// StreamReport; a version 2 client gets neither, at the server's fixed rate.
// Version 4: the session runs over TLS 1.3, UDP datagrams are sealed with keys exported from
// it (datagram_seal.h), and the Hello carries a signed connect token (connect_token.h).
// Older clients speak none of it, so they are not served.
// Version 5: brick updates may carry coarser precision levels (brick_precision.h), and acks
// and repair requests say which level each brick is held at; a version 4 client is sent the
// codec's own precision only.
// Version 6: a client sends its acks and repair requests as datagrams to the UDP port the
// SessionInfo names (uplink_datagram.h), sealed with the session's client->server key, and
// repeats in each ack the changes and arrivals of the two before it; a version 4 or 5 client
// acks over the stream as before, and its SessionInfo names no port.
// Version 7: session resume. The Hello names the field epoch the client's mirror holds, the
// SessionInfo the server's, and the client says what it holds in a Resume (a union member a
// version 6 server does not know, so it is sent only to version 7 servers); older clients get
// the whole field, as before.
// Version 8: runtime edits. A client whose token has the editor role sends Edit (a union
// member a version 7 server does not know, so it is sent only to version 8 servers) and hears
// an EditResult; the SceneState says which edits it includes, the lights edits added and the
// emission factors, which older clients ignore (they replay the animation as before).
// Version 9: cascades that follow the viewers. Bricks carry a layout stamp (the cascade's origin,
// a codec flag older clients refuse) and SceneState every cascade's place; a server whose
// cascades follow refuses older clients.
inline constexpr std::uint32_t kProtocolVersion = 9;
inline constexpr std::uint32_t kFirstMovingCascadesVersion = 9;
inline constexpr std::uint32_t kMinProtocolVersion = 4;
// The first version whose clients report arrivals and take StreamReport.
inline constexpr std::uint32_t kCongestionControlVersion = 3;
// The first version whose clients take coarser precision levels.
inline constexpr std::uint32_t kPrecisionLevelsVersion = 5;
// The first version whose clients send acks and repair requests as datagrams.
inline constexpr std::uint32_t kUplinkDatagramsVersion = 6;
// The first version whose clients and servers resume sessions (Resume, epochs).
inline constexpr std::uint32_t kResumeVersion = 7;
// The first version whose clients send Edit and whose servers answer it with EditResult.
inline constexpr std::uint32_t kEditsVersion = 8;

// UDP datagrams never exceed this (fits the IPv6 minimum MTU of 1280 with headers).
inline constexpr std::size_t kMaxDatagramBytes = 1200;
// Payload bytes per fragment: every fragment but a payload's last holds exactly this many,
// which leaves room for the datagram and fragment headers within kMaxDatagramBytes.
inline constexpr std::size_t kFragmentBytes = 1024;
// A session message (TCP) larger than this is refused before it is read.
inline constexpr std::size_t kMaxSessionMessageBytes = 4u << 20;

// Verifier limits. Session messages nest 3 tables deep (message, body, cascade); a datagram
// holds at most a few dozen fragment tables.
inline constexpr unsigned kMaxMessageDepth = 8;
inline constexpr unsigned kMaxMessageTables = 1024;
inline constexpr unsigned kMaxDatagramTables = 64;

}  // namespace pc
