// The session's byte stream: TLS 1.3 over TCP, or plain TCP where both ends were told to run
// without TLS (benchmarks of its cost, trusted loopback). One type for both, so the session
// code reads and writes the same way: it models Asio's AsyncReadStream and AsyncWriteStream,
// and asio::async_read / async_write work on it.
#pragma once

#include <memory>

#include "net/tls_context.h"

namespace pc::net {

class SessionStream {
 public:
  using tcp = boost::asio::ip::tcp;
  using executor_type = tcp::socket::executor_type;

  // Plain TCP.
  explicit SessionStream(tcp::socket socket) : plain_(std::move(socket)) {}
  // TLS over the socket, with the context's settings.
  SessionStream(tcp::socket socket, ssl::context& context)
      : plain_(socket.get_executor()),
        tls_(std::make_unique<ssl::stream<tcp::socket>>(std::move(socket), context)) {}

  bool tls() const { return tls_ != nullptr; }
  tcp::socket& socket() { return tls_ ? tls_->next_layer() : plain_; }
  const tcp::socket& socket() const { return tls_ ? tls_->next_layer() : plain_; }
  ssl::stream<tcp::socket>* tlsStream() { return tls_.get(); }
  executor_type get_executor() { return plain_.get_executor(); }

  // TLS: the handshake as `type`; plain: completes at once (posted, never inline).
  template <class Handler>
  void asyncHandshake(ssl::stream_base::handshake_type type, Handler&& handler) {
    if (tls_) return tls_->async_handshake(type, std::forward<Handler>(handler));
    boost::asio::post(plain_.get_executor(), [h = std::forward<Handler>(handler)]() mutable {
      h(boost::system::error_code{});
    });
  }

  template <class Buffers, class Handler>
  void async_read_some(const Buffers& buffers, Handler&& handler) {
    if (tls_) return tls_->async_read_some(buffers, std::forward<Handler>(handler));
    plain_.async_read_some(buffers, std::forward<Handler>(handler));
  }
  template <class Buffers, class Handler>
  void async_write_some(const Buffers& buffers, Handler&& handler) {
    if (tls_) return tls_->async_write_some(buffers, std::forward<Handler>(handler));
    plain_.async_write_some(buffers, std::forward<Handler>(handler));
  }

  // Ends the connection at once (no TLS close_notify: the peer learns from the TCP close,
  // and a peer that never reads cannot hold the close up).
  void close() {
    boost::system::error_code ec;
    socket().shutdown(tcp::socket::shutdown_both, ec);
    socket().close(ec);
  }

  // The datagram secret of this stream's TLS session (after the handshake).
  Result<std::array<std::uint8_t, 64>> datagramSecret() {
    if (!tls_) return Error{"no TLS session: datagrams cannot be sealed"};
    return exportDatagramSecret(tls_->native_handle());
  }

 private:
  tcp::socket plain_;  // the socket itself when plain; unused (never opened) with TLS
  std::unique_ptr<ssl::stream<tcp::socket>> tls_;
};

}  // namespace pc::net
