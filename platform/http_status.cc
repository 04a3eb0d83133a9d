#include "platform/http_status.h"

#include <cctype>

namespace sandswim {
namespace {

constexpr std::string_view kProblemPrefix = "urn:sandswim:problem:";

constexpr StatusCode kEveryError[] = {
    StatusCode::kInvalidArgument,   StatusCode::kNotFound,           StatusCode::kAlreadyExists,
    StatusCode::kConflict,          StatusCode::kFailedPrecondition, StatusCode::kResourceExhausted,
    StatusCode::kUnauthenticated,   StatusCode::kPermissionDenied,   StatusCode::kUnavailable,
    StatusCode::kIOError,           StatusCode::kCorruption,         StatusCode::kInternal,
};

StatusCode StatusCodeForHttp(int http_status) {
  switch (http_status) {
    case 401:
    case 403:
      return StatusCode::kUnauthenticated;
    case 404:
      return StatusCode::kNotFound;
    case 409:
      return StatusCode::kConflict;
    case 413:
      return StatusCode::kResourceExhausted;
    case 422:
      return StatusCode::kFailedPrecondition;
    case 502:
    case 503:
    case 504:
      return StatusCode::kUnavailable;
    default:
      return http_status >= 500 ? StatusCode::kInternal : StatusCode::kInvalidArgument;
  }
}

}  // namespace

int HttpStatusFor(StatusCode code) {
  switch (code) {
    case StatusCode::kOk:
      return 200;
    case StatusCode::kInvalidArgument:
      return 400;
    case StatusCode::kUnauthenticated:
      return 401;
    case StatusCode::kPermissionDenied:
      return 403;
    case StatusCode::kNotFound:
      return 404;
    case StatusCode::kAlreadyExists:
    case StatusCode::kConflict:
      return 409;
    case StatusCode::kFailedPrecondition:
    case StatusCode::kResourceExhausted:
      return 422;
    case StatusCode::kUnavailable:
      return 503;
    case StatusCode::kIOError:
    case StatusCode::kCorruption:
    case StatusCode::kInternal:
      return 500;
  }
  return 500;
}

std::string ProblemTypeFor(StatusCode code) {
  std::string slug;
  for (const char* c = StatusCodeName(code); *c != '\0'; ++c)
    slug += *c == ' ' || *c == '_' ? '-' : static_cast<char>(std::tolower(static_cast<unsigned char>(*c)));
  return std::string(kProblemPrefix) + slug;
}

StatusCode StatusCodeForAnswer(int http_status, std::string_view problem_type) {
  if (problem_type.substr(0, kProblemPrefix.size()) == kProblemPrefix) {
    for (StatusCode code : kEveryError)
      if (ProblemTypeFor(code) == problem_type) return code;
  }
  return StatusCodeForHttp(http_status);
}

}  // namespace sandswim
