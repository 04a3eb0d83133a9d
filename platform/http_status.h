// The one table between Status codes and HTTP: the daemon answers a Status with HttpStatusFor()
// and a problem+json whose "type" is ProblemTypeFor(); the CLI, the worker and the notebook
// client read an answer back with StatusCodeForAnswer(). Several codes share an HTTP status (409,
// 422, 500), so the problem's type, not the number, carries the code back; the number alone is
// the fallback for answers that are not the daemon's (a proxy's 502, a bare 404).
//
//   Status               HTTP  problem type (urn:sandswim:problem:...)
//   kInvalidArgument     400   invalid-argument      bad input; the problem's "field" names it
//   kUnauthenticated     401   unauthenticated       no or a wrong token
//   kPermissionDenied    403   permission-denied     a write from another site's page
//   kNotFound            404   not-found
//   kAlreadyExists       409   already-exists
//   kConflict            409   conflict              a lease lost, an idempotency key reused
//   kFailedPrecondition  422   failed-precondition   a valid request the daemon cannot do
//   kResourceExhausted   422   resource-exhausted    a sweep past the run limit
//   kUnavailable         503   unavailable           cannot answer now (Retry-After)
//   kIOError             500   i/o-error             the daemon's disk
//   kCorruption          500   corruption            a row or file that does not parse
//   kInternal            500   internal              the daemon failed
//
// Thread safety: pure functions.
#ifndef SANDSWIM_PLATFORM_HTTP_STATUS_H_
#define SANDSWIM_PLATFORM_HTTP_STATUS_H_

#include <string>
#include <string_view>

#include "core/status.h"

namespace sandswim {

// The HTTP status the daemon answers a Status with (200 for OK).
int HttpStatusFor(StatusCode code);

// "urn:sandswim:problem:" + the code's name with '-' for spaces ("...:not-found").
std::string ProblemTypeFor(StatusCode code);

// The code of an answer: the one its problem type names when it is one of ProblemTypeFor()'s,
// else from the HTTP status alone (401/403 kUnauthenticated, 404 kNotFound, 409 kConflict, 413
// kResourceExhausted, 422 kFailedPrecondition, 502-504 kUnavailable, other 5xx kInternal, other
// 4xx kInvalidArgument).
StatusCode StatusCodeForAnswer(int http_status, std::string_view problem_type = {});

}  // namespace sandswim

#endif  // SANDSWIM_PLATFORM_HTTP_STATUS_H_
