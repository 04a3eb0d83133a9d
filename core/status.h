// Status and Result: the error vocabulary of sandswim's domain code.
//
// Domain functions return Status (or Result<T>) instead of throwing. A Status carries a code, the
// field it is about (a JSON-pointer-like path such as "base.A" or "axes[0].values[2]"; empty when
// no field is to blame) and a reason a user can act on. Adapters (routes, store, launcher) convert
// third-party exceptions into Status at their boundary; routes map codes to HTTP with one table.
//
// Thread safety: values; copy freely.
#ifndef SANDSWIM_CORE_STATUS_H_
#define SANDSWIM_CORE_STATUS_H_

#include <optional>
#include <string>
#include <utility>
#include <variant>

namespace sandswim {

enum class StatusCode {
  kOk = 0,
  kInvalidArgument,  // bad user input; `field` names it
  kNotFound,
  kAlreadyExists,
  kConflict,            // e.g. a lease that is no longer held
  kFailedPrecondition,  // e.g. a point the scale cannot take
  kResourceExhausted,   // e.g. a sweep past the run limit, a body too large
  kUnauthenticated,
  kPermissionDenied,  // e.g. a write from a web page of another site
  kUnavailable,       // a peer (daemon, engine) that does not answer
  kIOError,
  kCorruption,  // a file or row that does not parse
  kInternal,
};

const char* StatusCodeName(StatusCode code);

// [[nodiscard]]: a Status dropped on the floor is a failure nobody sees; (void) says "on purpose".
class [[nodiscard]] Status {
 public:
  Status() = default;  // OK
  Status(StatusCode code, std::string reason, std::string field = "")
      : code_(code), reason_(std::move(reason)), field_(std::move(field)) {}

  static Status Ok() { return Status(); }
  static Status InvalidArgument(std::string field, std::string reason) {
    return Status(StatusCode::kInvalidArgument, std::move(reason), std::move(field));
  }
  static Status NotFound(std::string reason) { return Status(StatusCode::kNotFound, std::move(reason)); }
  static Status Conflict(std::string reason) { return Status(StatusCode::kConflict, std::move(reason)); }
  static Status FailedPrecondition(std::string field, std::string reason) {
    return Status(StatusCode::kFailedPrecondition, std::move(reason), std::move(field));
  }
  static Status ResourceExhausted(std::string field, std::string reason) {
    return Status(StatusCode::kResourceExhausted, std::move(reason), std::move(field));
  }
  static Status Unavailable(std::string reason) { return Status(StatusCode::kUnavailable, std::move(reason)); }
  static Status IOError(std::string reason) { return Status(StatusCode::kIOError, std::move(reason)); }
  static Status Corruption(std::string reason) { return Status(StatusCode::kCorruption, std::move(reason)); }
  static Status Internal(std::string reason) { return Status(StatusCode::kInternal, std::move(reason)); }

  bool ok() const { return code_ == StatusCode::kOk; }
  StatusCode code() const { return code_; }
  const std::string& reason() const { return reason_; }
  const std::string& field() const { return field_; }

  // Prefixes the field path: Status for "A" inside "base" becomes "base.A".
  Status WithFieldPrefix(const std::string& prefix) const;
  // "invalid argument: base.A: must be > 0"
  std::string ToString() const;

 private:
  StatusCode code_ = StatusCode::kOk;
  std::string reason_;
  std::string field_;
};

// Result<T>: a T or a non-OK Status. Made from an OK Status (a bug: there is no value), it holds an
// Internal error saying so rather than a Result that is neither.
template <typename T>
class [[nodiscard]] Result {
 public:
  Result(T value) : v_(std::move(value)) {}  // NOLINT: implicit by design
  Result(Status status)                      // NOLINT: implicit by design
      : v_(status.ok() ? Status::Internal("a Result was made from an OK status, without a value")
                       : std::move(status)) {}
  bool ok() const { return std::holds_alternative<T>(v_); }
  const Status& status() const {
    static const Status kOk;
    return ok() ? kOk : std::get<Status>(v_);
  }
  T& value() & { return std::get<T>(v_); }
  const T& value() const& { return std::get<T>(v_); }
  T&& value() && { return std::get<T>(std::move(v_)); }
  T* operator->() { return &value(); }
  const T* operator->() const { return &value(); }
  T& operator*() & { return value(); }
  const T& operator*() const& { return value(); }

 private:
  std::variant<T, Status> v_;
};

}  // namespace sandswim

#define SANDSWIM_RETURN_IF_ERROR(expr) \
  do {                                 \
    ::sandswim::Status _s = (expr);    \
    if (!_s.ok()) return _s;           \
  } while (0)

#endif  // SANDSWIM_CORE_STATUS_H_
