#include "platform/http_status.h"

#include <gtest/gtest.h>

namespace sandswim {
namespace {

constexpr StatusCode kEveryError[] = {
    StatusCode::kInvalidArgument, StatusCode::kNotFound,         StatusCode::kAlreadyExists,
    StatusCode::kConflict,        StatusCode::kFailedPrecondition, StatusCode::kResourceExhausted,
    StatusCode::kUnauthenticated, StatusCode::kPermissionDenied, StatusCode::kUnavailable,
    StatusCode::kIOError,         StatusCode::kCorruption,       StatusCode::kInternal,
};

TEST(HttpStatusTest, EveryCodeRoundTripsThroughTheDaemonsAnswer) {
  for (StatusCode code : kEveryError) {
    int http = HttpStatusFor(code);
    EXPECT_GE(http, 400) << StatusCodeName(code);
    EXPECT_EQ(StatusCodeForAnswer(http, ProblemTypeFor(code)), code)
        << StatusCodeName(code) << " -> HTTP " << http << " " << ProblemTypeFor(code);
  }
}

TEST(HttpStatusTest, SharedHttpStatusesAreToldApartByTheProblemType) {
  EXPECT_EQ(HttpStatusFor(StatusCode::kResourceExhausted), HttpStatusFor(StatusCode::kFailedPrecondition));
  EXPECT_EQ(StatusCodeForAnswer(422, "urn:sandswim:problem:resource-exhausted"), StatusCode::kResourceExhausted);
  EXPECT_EQ(StatusCodeForAnswer(422), StatusCode::kFailedPrecondition);
  EXPECT_EQ(StatusCodeForAnswer(403, "urn:sandswim:problem:permission-denied"), StatusCode::kPermissionDenied);
}

TEST(HttpStatusTest, AnswersThatAreNotTheDaemonsFallBackToTheNumber) {
  EXPECT_EQ(StatusCodeForAnswer(502), StatusCode::kUnavailable);
  EXPECT_EQ(StatusCodeForAnswer(404, "about:blank"), StatusCode::kNotFound);
  EXPECT_EQ(StatusCodeForAnswer(500, "urn:sandswim:problem:no-such-code"), StatusCode::kInternal);
  EXPECT_EQ(StatusCodeForAnswer(418), StatusCode::kInvalidArgument);
  EXPECT_EQ(ProblemTypeFor(StatusCode::kNotFound), "urn:sandswim:problem:not-found");
}

}  // namespace
}  // namespace sandswim
