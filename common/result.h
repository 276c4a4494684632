// Recoverable errors as values: a bad file, a bad message or a lost peer yields an Error with
// a message naming what was wrong, never an exception across a module boundary or a crash.
#pragma once

#include <optional>
#include <string>
#include <utility>
#include <variant>

namespace pc {

struct Error {
  std::string message;
};

template <typename T>
class Result {
 public:
  Result(T value) : v_(std::move(value)) {}
  Result(Error error) : v_(std::move(error)) {}

  bool ok() const { return v_.index() == 0; }
  explicit operator bool() const { return ok(); }
  T& value() & { return std::get<0>(v_); }
  const T& value() const& { return std::get<0>(v_); }
  T&& value() && { return std::get<0>(std::move(v_)); }
  T* operator->() { return &value(); }
  const T* operator->() const { return &value(); }
  T& operator*() & { return value(); }
  const Error& error() const { return std::get<1>(v_); }

 private:
  std::variant<T, Error> v_;
};

// For operations that return nothing but may fail.
struct Status {
  std::optional<Error> err;
  static Status success() { return {}; }
  Status() = default;
  Status(Error e) : err(std::move(e)) {}
  bool ok() const { return !err.has_value(); }
  explicit operator bool() const { return ok(); }
  const Error& error() const { return *err; }
};

}  // namespace pc
