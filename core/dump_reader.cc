#include "core/dump_reader.h"

#include <charconv>
#include <cstdint>
#include <cmath>
#include <cstring>
#include <utility>

namespace sandswim {
namespace {

inline bool IsSpace(char c) { return c == ' ' || c == '\t' || c == '\r'; }

// Next whitespace-separated token of `s` from `*pos`; empty at the end.
inline std::string_view NextToken(std::string_view s, size_t* pos) {
  size_t i = *pos;
  while (i < s.size() && IsSpace(s[i])) ++i;
  size_t start = i;
  while (i < s.size() && !IsSpace(s[i])) ++i;
  *pos = i;
  return s.substr(start, i - start);
}

inline bool ParseDouble(std::string_view tok, double* out) {
  if (tok.empty()) return false;
  const char* first = tok.data();
  if (*first == '+') ++first;  // from_chars refuses a leading '+'; LAMMPS never writes one, others may
  auto [ptr, ec] = std::from_chars(first, tok.data() + tok.size(), *out);
  if (ec == std::errc::result_out_of_range) {
    // Denormal-small values read as 0; an overflow is a real problem.
    if (std::fabs(*out) < 1.0) return ptr == tok.data() + tok.size();
    return false;
  }
  return ec == std::errc() && ptr == tok.data() + tok.size();
}

// Clinger's fast path: a decimal with at most 15 significant digits and a small power of ten is
// one exactly-representable integer times or over an exactly-representable power of ten, so a
// single IEEE multiplication or division gives the correctly rounded double (the same value
// from_chars gives). LIGGGHTS writes %g (6 digits), so nearly every value takes this path.
// Returns the end of the number, or nullptr when the text needs the general parser.
inline const char* FastDouble(const char* p, const char* end, double* out) {
  static constexpr double kPow10[] = {1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,  1e8,  1e9,  1e10, 1e11,
                                      1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};
  bool neg = false;
  if (p < end && *p == '-') {
    neg = true;
    ++p;
  }
  uint64_t mant = 0;
  int digits = 0, exp10 = 0;
  const char* start = p;
  while (p < end && *p >= '0' && *p <= '9') {
    if (digits > 0 || *p != '0') ++digits;
    mant = mant * 10 + static_cast<uint64_t>(*p - '0');
    ++p;
  }
  bool any = p > start;
  if (p < end && *p == '.') {
    ++p;
    const char* frac = p;
    while (p < end && *p >= '0' && *p <= '9') {
      if (digits > 0 || *p != '0') ++digits;
      mant = mant * 10 + static_cast<uint64_t>(*p - '0');
      --exp10;
      ++p;
    }
    any = any || p > frac;
  }
  if (!any || digits > 15) return nullptr;
  if (p < end && (*p == 'e' || *p == 'E')) {
    ++p;
    bool eneg = false;
    if (p < end && (*p == '-' || *p == '+')) eneg = *p++ == '-';
    if (p >= end || *p < '0' || *p > '9') return nullptr;
    int e = 0;
    while (p < end && *p >= '0' && *p <= '9' && e < 10000) e = e * 10 + (*p++ - '0');
    exp10 += eneg ? -e : e;
  }
  if (exp10 < -22 || exp10 > 22) return nullptr;
  double v = static_cast<double>(mant);
  v = exp10 < 0 ? v / kPow10[-exp10] : v * kPow10[exp10];
  *out = neg ? -v : v;
  return p;
}

inline bool ParseInt(std::string_view tok, int64_t* out) {
  if (tok.empty()) return false;
  auto [ptr, ec] = std::from_chars(tok.data(), tok.data() + tok.size(), *out);
  return ec == std::errc() && ptr == tok.data() + tok.size();
}

std::string_view Trim(std::string_view s) {
  while (!s.empty() && IsSpace(s.front())) s.remove_prefix(1);
  while (!s.empty() && IsSpace(s.back())) s.remove_suffix(1);
  return s;
}

bool StartsWith(std::string_view s, std::string_view prefix) {
  return s.size() >= prefix.size() && s.compare(0, prefix.size(), prefix) == 0;
}

std::string Shorten(std::string_view s) {
  constexpr size_t kMax = 60;
  if (s.size() <= kMax) return std::string(s);
  return std::string(s.substr(0, kMax)) + "...";
}

}  // namespace

int DumpFrame::Column(std::string_view name) const {
  for (size_t i = 0; i < columns.size(); ++i) {
    if (columns[i] == name) return static_cast<int>(i);
  }
  return -1;
}

Status DumpReader::Error(const std::string& what) const {
  return Status::Corruption("dump line " + std::to_string(line_) + ": " + what);
}

Status DumpReader::Feed(std::string_view chunk) {
  if (!status_.ok()) return status_;
  bytes_fed_ += chunk.size();
  // Finish the line carried over from the previous chunk first.
  if (!pending_.empty()) {
    const char* nl = static_cast<const char*>(std::memchr(chunk.data(), '\n', chunk.size()));
    if (nl == nullptr) {
      pending_.append(chunk);
      return Status::Ok();
    }
    size_t n = nl - chunk.data();
    pending_.append(chunk.substr(0, n));
    chunk.remove_prefix(n + 1);
    std::string line = std::move(pending_);
    pending_.clear();
    ++line_;
    status_ = ParseLine(line);
    if (!status_.ok()) return status_;
  }
  while (!chunk.empty()) {
    const char* nl = static_cast<const char*>(std::memchr(chunk.data(), '\n', chunk.size()));
    if (nl == nullptr) {
      pending_.assign(chunk);
      break;
    }
    size_t n = nl - chunk.data();
    ++line_;
    status_ = ParseLine(chunk.substr(0, n));
    if (!status_.ok()) return status_;
    chunk.remove_prefix(n + 1);
  }
  return Status::Ok();
}

Status DumpReader::ParseLine(std::string_view line) {
  switch (state_) {
    case State::kItemTimestep: {
      std::string_view t = Trim(line);
      if (t.empty()) return Status::Ok();  // tolerate blank lines between frames
      if (t != "ITEM: TIMESTEP") return Error("expected 'ITEM: TIMESTEP', got '" + Shorten(t) + "'");
      frame_ = DumpFrame();
      state_ = State::kTimestep;
      return Status::Ok();
    }
    case State::kTimestep: {
      std::string_view t = Trim(line);
      if (!ParseInt(t, &frame_.step) || frame_.step < 0) {
        return Error("expected a timestep (a non-negative integer), got '" + Shorten(t) + "'");
      }
      state_ = State::kItemNumber;
      return Status::Ok();
    }
    case State::kItemNumber: {
      std::string_view t = Trim(line);
      if (t != "ITEM: NUMBER OF ATOMS") {
        return Error("expected 'ITEM: NUMBER OF ATOMS', got '" + Shorten(t) + "'");
      }
      state_ = State::kNumber;
      return Status::Ok();
    }
    case State::kNumber: {
      std::string_view t = Trim(line);
      if (!ParseInt(t, &frame_.atoms) || frame_.atoms < 0) {
        return Error("expected a number of atoms (a non-negative integer), got '" + Shorten(t) + "'");
      }
      state_ = State::kItemBox;
      return Status::Ok();
    }
    case State::kItemBox: {
      std::string_view t = Trim(line);
      if (!StartsWith(t, "ITEM: BOX BOUNDS")) {
        return Error("expected 'ITEM: BOX BOUNDS', got '" + Shorten(t) + "'");
      }
      box_lines_ = 0;
      state_ = State::kBox;
      return Status::Ok();
    }
    case State::kBox: {
      size_t pos = 0;
      int n = 0;
      for (std::string_view tok = NextToken(line, &pos); !tok.empty(); tok = NextToken(line, &pos)) {
        double v;
        if (!ParseDouble(tok, &v)) return Error("expected box bounds (numbers), got '" + Shorten(tok) + "'");
        ++n;
      }
      if (n != 2 && n != 3) return Error("expected 2 or 3 box bound numbers, got " + std::to_string(n));
      if (++box_lines_ == 3) state_ = State::kItemAtoms;
      return Status::Ok();
    }
    case State::kItemAtoms: {
      std::string_view t = Trim(line);
      if (!StartsWith(t, "ITEM: ATOMS")) return Error("expected 'ITEM: ATOMS', got '" + Shorten(t) + "'");
      t.remove_prefix(std::strlen("ITEM: ATOMS"));
      size_t pos = 0;
      for (std::string_view tok = NextToken(t, &pos); !tok.empty(); tok = NextToken(t, &pos)) {
        frame_.columns.emplace_back(tok);
      }
      if (frame_.columns.empty()) return Error("'ITEM: ATOMS' names no columns");
      frame_.values.clear();
      frame_.values.reserve(frame_.atoms * frame_.columns.size());
      atoms_read_ = 0;
      state_ = State::kAtoms;
      if (frame_.atoms == 0) {
        done_.push_back(std::move(frame_));
        state_ = State::kItemTimestep;
      }
      return Status::Ok();
    }
    case State::kAtoms: {
      // The hot loop: one from_chars per value straight over the line, no token copies.
      const char* p = line.data();
      const char* end = p + line.size();
      const size_t ncol = frame_.columns.size();
      for (size_t c = 0; c < ncol; ++c) {
        while (p < end && IsSpace(*p)) ++p;
        double v;
        const char* q = FastDouble(p, end, &v);
        if (q == nullptr || (q < end && !IsSpace(*q))) {
          // Slow path: a '+' sign, a denormal, or really not a number.
          const char* tok_end = p;
          while (tok_end < end && !IsSpace(*tok_end)) ++tok_end;
          std::string_view tok(p, tok_end - p);
          if (tok.empty()) {
            return Error("atom line has " + std::to_string(c) + " values, expected " + std::to_string(ncol));
          }
          if (!ParseDouble(tok, &v)) {
            return Error("column '" + frame_.columns[c] + "': '" + Shorten(tok) + "' is not a number");
          }
          q = tok_end;
        }
        frame_.values.push_back(v);
        p = q;
      }
      while (p < end && IsSpace(*p)) ++p;
      if (p != end) return Error("atom line has more than " + std::to_string(ncol) + " values");
      if (++atoms_read_ == frame_.atoms) {
        done_.push_back(std::move(frame_));
        frame_ = DumpFrame();
        state_ = State::kItemTimestep;
      }
      return Status::Ok();
    }
  }
  return Status::Internal("unreachable dump reader state");
}

std::vector<DumpFrame> DumpReader::TakeFrames() {
  std::vector<DumpFrame> out(std::make_move_iterator(done_.begin()), std::make_move_iterator(done_.end()));
  done_.clear();
  return out;
}

Status DumpReader::Finish() { return status_; }

Result<std::vector<DumpFrame>> ReadDump(std::string_view text) {
  DumpReader reader;
  Status s = reader.Feed(text);
  if (!s.ok()) return s;
  return reader.TakeFrames();
}

}  // namespace sandswim
