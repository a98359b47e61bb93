// Status and Expected<T>: the one error model between lightlink modules.
//
// Modules return Expected<T> (a value or a Status) instead of throwing across module
// boundaries; the CLI turns a Status into a message and an exit code, the service into a
// gRPC status, in one place each. The Code says *whose* fault it is (bad input vs our
// failure), which is what exit codes and gRPC codes need; the message names the file,
// the object and what is wrong.
#pragma once

#include <cassert>
#include <string>
#include <utility>
#include <variant>

#include <fmt/format.h>

namespace lightlink {

enum class Code {
  kOk = 0,
  kInvalidInput,    // the user's data or parameters are wrong (malformed glTF, NaN, ...)
  kUnsupported,     // valid input that lightlink does not handle (Draco, lines, ...)
  kNotFound,        // a file or named object that does not exist
  kIoError,         // reading or writing failed at the OS level
  kInternal,        // a bug or a failed invariant on our side
  kResourceExhausted,  // a request over a budget (docs/cli.md "Limits"), or out of memory
  kCancelled,       // the caller stopped the work (a deadline, a closed client, a shutdown)
};

const char* codeName(Code code);

class [[nodiscard]] Status {
 public:
  Status() = default;
  Status(Code code, std::string message) : code_(code), message_(std::move(message)) {}

  static Status ok() { return {}; }
  bool isOk() const { return code_ == Code::kOk; }
  explicit operator bool() const { return isOk(); }
  Code code() const { return code_; }
  const std::string& message() const { return message_; }
  std::string toString() const;

 private:
  Code code_ = Code::kOk;
  std::string message_;
};

template <typename... Args>
Status invalidInput(fmt::format_string<Args...> f, Args&&... args) {
  return {Code::kInvalidInput, fmt::format(f, std::forward<Args>(args)...)};
}
template <typename... Args>
Status unsupported(fmt::format_string<Args...> f, Args&&... args) {
  return {Code::kUnsupported, fmt::format(f, std::forward<Args>(args)...)};
}
template <typename... Args>
Status ioError(fmt::format_string<Args...> f, Args&&... args) {
  return {Code::kIoError, fmt::format(f, std::forward<Args>(args)...)};
}
template <typename... Args>
Status notFound(fmt::format_string<Args...> f, Args&&... args) {
  return {Code::kNotFound, fmt::format(f, std::forward<Args>(args)...)};
}
template <typename... Args>
Status resourceExhausted(fmt::format_string<Args...> f, Args&&... args) {
  return {Code::kResourceExhausted, fmt::format(f, std::forward<Args>(args)...)};
}
template <typename... Args>
Status cancelled(fmt::format_string<Args...> f, Args&&... args) {
  return {Code::kCancelled, fmt::format(f, std::forward<Args>(args)...)};
}
template <typename... Args>
Status internalError(fmt::format_string<Args...> f, Args&&... args) {
  return {Code::kInternal, fmt::format(f, std::forward<Args>(args)...)};
}

// A value or the Status that explains why there is none.
template <typename T>
class [[nodiscard]] Expected {
 public:
  Expected(T value) : v_(std::move(value)) {}  // NOLINT(implicit)
  Expected(Status status) : v_(std::move(status)) {  // NOLINT(implicit)
    assert(!std::get<Status>(v_).isOk() && "Expected built from an OK status");
  }

  bool hasValue() const { return std::holds_alternative<T>(v_); }
  explicit operator bool() const { return hasValue(); }

  T& value() & { return std::get<T>(v_); }
  const T& value() const& { return std::get<T>(v_); }
  T&& value() && { return std::get<T>(std::move(v_)); }
  T* operator->() { return &value(); }
  const T* operator->() const { return &value(); }
  T& operator*() & { return value(); }
  const T& operator*() const& { return value(); }

  const Status& status() const {
    static const Status kOk;
    return hasValue() ? kOk : std::get<Status>(v_);
  }

 private:
  std::variant<T, Status> v_;
};

}  // namespace lightlink
