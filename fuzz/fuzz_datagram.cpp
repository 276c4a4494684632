// Datagrams (protocol/datagram.h): decodeDatagram on any bytes returns a datagram or an Error.
// The input is tried as received (mostly stopped by the CRC) and with a valid CRC-32 appended,
// so that mutations reach the flatbuffer and fragment checks. Decoded fragments then go through
// a small Reassembler, as on a client, whose memory must stay within its caps.
#include <cstddef>
#include <cstdint>
#include <cstdlib>

#include "protocol/crc32.h"
#include "protocol/datagram.h"

namespace {

using namespace pc;

void reassemble(Datagram& d) {
  ReassemblyOptions options;
  options.maxUpdates = 4;
  options.maxBytes = 64 * 1024;
  Reassembler r(options);
  double now = 0.0;
  for (Fragment& f : d.fragments) {
    const UpdateHeader header = f.update;
    std::optional<CompletedUpdate> done = r.add(std::move(f), now);
    if (done && (done->payload.size() != header.totalSize || !done->update.sameUpdate(header)))
      std::abort();
    if (r.pendingUpdates() > options.maxUpdates) std::abort();
    now += 0.25;
  }
  r.expire(now + 10.0);
  if (r.pendingUpdates() != 0 || r.pendingBytes() != 0) std::abort();
}

void check(std::span<const std::uint8_t> bytes) {
  Result<Datagram> d = decodeDatagram(bytes);
  if (!d) return;
  // Re-encoding the decoded fragments gives a datagram that decodes to the same values.
  std::vector<FragmentRef> refs;
  for (const Fragment& f : d->fragments) refs.push_back(FragmentRef{f.update, f.index, f.data});
  const std::vector<std::uint8_t> again =
      encodeDatagram(d->sessionId, d->sequence, d->fieldVersion, refs);
  // A hostile sender may share one data vector between fragments; the re-encoding does not,
  // so it may outgrow the datagram limit.
  if (again.size() > kMaxDatagramBytes) return reassemble(d.value());
  Result<Datagram> e = decodeDatagram(again);
  if (!e || e->sessionId != d->sessionId || e->sequence != d->sequence ||
      e->fieldVersion != d->fieldVersion || e->fragments.size() != d->fragments.size())
    std::abort();
  for (std::size_t i = 0; i < d->fragments.size(); ++i) {
    const Fragment &a = d->fragments[i], &b = e->fragments[i];
    if (!a.update.sameUpdate(b.update) || a.index != b.index || a.count != b.count ||
        a.data != b.data)
      std::abort();
  }
  reassemble(d.value());
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  check(std::span<const std::uint8_t>(data, size));
  std::vector<std::uint8_t> sealed(data, data + size);
  const std::uint32_t crc = crc32(sealed);
  for (int i = 0; i < 4; ++i) sealed.push_back(std::uint8_t(crc >> (8 * i)));
  check(sealed);
  return 0;
}
