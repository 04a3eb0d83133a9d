#include "core/dump_reader.h"
#include "core/text.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <utility>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#if !defined(__BYTE_ORDER__) || __BYTE_ORDER__ != __ORDER_LITTLE_ENDIAN__
#error "dump_reader.cc's 8-byte number parser assumes a little-endian machine"
#endif

namespace sandswim {
namespace {

inline bool IsSpace(char c) { return c == ' ' || c == '\t' || c == '\r'; }
inline bool IsDigit(char c) { return static_cast<unsigned char>(c - '0') < 10; }

// Next whitespace-separated token of `s` from `*pos`; empty at the end.
inline std::string_view NextToken(std::string_view s, size_t* pos) {
  size_t i = *pos;
  while (i < s.size() && IsSpace(s[i])) ++i;
  size_t start = i;
  while (i < s.size() && !IsSpace(s[i])) ++i;
  *pos = i;
  return s.substr(start, i - start);
}

// The general number parser: std::from_chars, plus a leading '+' and denormals.
inline bool ParseDouble(std::string_view tok, double* out) {
  if (tok.empty()) return false;
  const char* first = tok.data();
  if (*first == '+') ++first;  // from_chars refuses a leading '+'; LAMMPS never writes one, others may
  if (first < tok.data() + tok.size() && *first == '-' && first != tok.data()) return false;  // "+-1"
  auto [ptr, ec] = std::from_chars(first, tok.data() + tok.size(), *out);
  if (ec == std::errc::result_out_of_range) {
    // Denormal-small values read as 0; an overflow is a real problem.
    if (std::fabs(*out) < 1.0) return ptr == tok.data() + tok.size();
    return false;
  }
  return ec == std::errc() && ptr == tok.data() + tok.size();
}

constexpr double kPow10[] = {1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,  1e8,  1e9,  1e10, 1e11,
                             1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};
constexpr uint64_t kPow10Int[] = {1, 10, 100, 1000, 10000, 100000, 1000000, 10000000, 100000000};
constexpr uint64_t kTwoTo53 = uint64_t{1} << 53;

// Clinger's fast path: a decimal whose digits form an integer m <= 2^53 and whose power of ten
// is within +-22 is m times or over an exactly-representable power of ten, so one IEEE
// multiplication or division gives the correctly rounded double (the value from_chars gives).
inline double Clinger(uint64_t mant, int exp10, bool neg) {
  double v = static_cast<double>(mant);
  v = exp10 < 0 ? v / kPow10[-exp10] : v * kPow10[exp10];
  return neg ? -v : v;
}

// Scalar fast path over a line that ends in '\n' (the sentinel: no bounds checks are needed).
// Reads [-]digits[.digits][(e|E)[+-]digits] from p; returns the end, or nullptr when the text
// needs the general parser (no digits, too many digits, a big exponent, a '+' sign ...).
inline const char* ScanDouble(const char* p, double* out) {
  bool neg = *p == '-';
  p += neg;
  uint64_t mant = 0;
  int digits = 0, exp10 = 0;
  const char* start = p;
  while (IsDigit(*p)) {
    mant = mant * 10 + static_cast<uint64_t>(*p - '0');
    ++p;
  }
  digits = static_cast<int>(p - start);
  if (*p == '.') {
    ++p;
    const char* frac = p;
    while (IsDigit(*p)) {
      mant = mant * 10 + static_cast<uint64_t>(*p - '0');
      ++p;
    }
    exp10 = -static_cast<int>(p - frac);
    digits -= exp10;
  }
  if (digits == 0 || digits > 19 || mant > kTwoTo53) return nullptr;
  if ((*p | 0x20) == 'e') {
    ++p;
    bool eneg = *p == '-';
    p += (*p == '-' || *p == '+');
    if (!IsDigit(*p)) return nullptr;
    int e = 0;
    while (IsDigit(*p) && e < 10000) e = e * 10 + (*p++ - '0');
    exp10 += eneg ? -e : e;
  }
  if (exp10 < -22 || exp10 > 22) return nullptr;
  *out = Clinger(mant, exp10, neg);
  return p;
}

// --- 8 bytes at a time -------------------------------------------------------------------------

inline uint64_t Load64(const char* p) {
  uint64_t w;
  std::memcpy(&w, p, sizeof(w));
  return w;
}

constexpr uint64_t kBytes(uint8_t b) { return 0x0101010101010101ULL * b; }

// t = bytes ^ '0'...: the high bit of each byte that is not a digit (no carries between bytes).
inline uint64_t NonDigits(uint64_t t) { return (((t & kBytes(0x7F)) + kBytes(0x76)) | t) & kBytes(0x80); }

// The value of 8 digits in t (= bytes ^ '0'..., first character in the low byte).
inline uint64_t EightDigits(uint64_t v) {
  v = (v * 10) + (v >> 8);
  v = (((v & 0x000000FF000000FFULL) * (100 + (1000000ULL << 32))) +
       (((v >> 16) & 0x000000FF000000FFULL) * (1 + (10000ULL << 32)))) >>
      32;
  return v & 0xFFFFFFFF;
}

// The value of the first n (0..7) digits of t: the bytes after them are shifted out, and the
// zero bytes shifted in are leading zeros.
inline uint64_t DigitsValue(uint64_t t, int n) { return EightDigits((t << (8 * (7 - n))) << 8); }

// Reads the run of digits at *q into *mant (mant * 10^len + run), 8 bytes at a time; *digits
// counts the digits read so far. False when the number has more than 19 digits (may overflow).
inline bool DigitRun(const char** q, uint64_t* mant, int* digits) {
  for (;;) {
    if (*digits > 19) return false;
    uint64_t t = Load64(*q) ^ kBytes('0');
    uint64_t nd = NonDigits(t);
    if (nd != 0) {
      int n = __builtin_ctzll(nd) >> 3;
      *mant = *mant * kPow10Int[n] + DigitsValue(t, n);
      *q += n;
      *digits += n;
      return *digits <= 19;
    }
    *mant = *mant * 100000000 + EightDigits(t);
    *q += 8;
    *digits += 8;
  }
}

// The number token [s, e) (no blanks inside, e - s < 64, at least 32 readable bytes after s):
// true with *out when it is a plain decimal that Clinger's fast path reads exactly (what %g
// writes); false when it needs ScanDouble / the general parser, or is not a number.
inline bool SwarDouble(const char* s, const char* e, double* out) {
  bool neg = *s == '-';
  const char* q = s + neg;
  uint64_t mant = 0;
  int digits = 0;
  // Reads stay below s + 1 + 21 + 8: a load happens only while at most 19 digits were read.
  if (!DigitRun(&q, &mant, &digits)) return false;
  int exp10 = 0;
  if (*q == '.') {
    ++q;
    const char* frac = q;
    if (!DigitRun(&q, &mant, &digits)) return false;
    exp10 = -static_cast<int>(q - frac);
  }
  if (digits == 0 || mant > kTwoTo53) return false;
  if ((*q | 0x20) == 'e') {
    ++q;
    bool eneg = *q == '-';
    q += (*q == '-' || *q == '+');
    if (!IsDigit(*q)) return false;
    int ev = *q++ - '0';
    if (IsDigit(*q)) ev = ev * 10 + (*q++ - '0');
    if (IsDigit(*q)) return false;  // three or more exponent digits: let ScanDouble decide
    exp10 += eneg ? -ev : ev;
  }
  if (q != e || exp10 < -22 || exp10 > 22) return false;
  *out = Clinger(mant, exp10, neg);
  return true;
}

// For the 64 bytes at p: bit i of *blank set when p[i] is a blank or a control character (<= ' '),
// bit i of *dot when p[i] is '.'.
inline void Masks64(const char* p, uint64_t* blank, uint64_t* dot) {
#if defined(__SSE2__)
  const __m128i space = _mm_set1_epi8(' ');
  const __m128i period = _mm_set1_epi8('.');
  uint64_t b = 0, d = 0;
  for (int k = 0; k < 4; ++k) {
    __m128i v = _mm_loadu_si128(reinterpret_cast<const __m128i*>(p + 16 * k));
    __m128i le = _mm_cmpeq_epi8(_mm_min_epu8(v, space), v);
    b |= static_cast<uint64_t>(static_cast<uint32_t>(_mm_movemask_epi8(le))) << (16 * k);
    d |= static_cast<uint64_t>(static_cast<uint32_t>(_mm_movemask_epi8(_mm_cmpeq_epi8(v, period)))) << (16 * k);
  }
  *blank = b;
  *dot = d;
#else
  uint64_t b = 0, d = 0;
  for (int i = 0; i < 64; ++i) {
    b |= static_cast<uint64_t>(static_cast<unsigned char>(p[i]) <= ' ') << i;
    d |= static_cast<uint64_t>(p[i] == '.') << i;
  }
  *blank = b;
  *dot = d;
#endif
}

// kLowMask[n]: the low n (0..8) bytes.
constexpr uint64_t kLowMask[9] = {
    0, 0xFFULL, 0xFFFFULL, 0xFFFFFFULL, 0xFFFFFFFFULL, 0xFFFFFFFFFFULL, 0xFFFFFFFFFFFFULL, 0xFFFFFFFFFFFFFFULL, ~0ULL};
constexpr uint64_t kPow10U64[] = {1,
                                  10,
                                  100,
                                  1000,
                                  10000,
                                  100000,
                                  1000000,
                                  10000000,
                                  100000000,
                                  1000000000,
                                  10000000000,
                                  100000000000,
                                  1000000000000,
                                  10000000000000,
                                  100000000000000,
                                  1000000000000000,
                                  10000000000000000};

// The value of the first n (0..8) digit bytes of t (= bytes ^ '0'...; the bytes after them are
// ignored), without a branch: they are moved to the top bytes, the zero bytes below being
// leading zeros. (Two shifts: a shift by 64 would be undefined.)
inline uint64_t FirstDigits(uint64_t t, int n) {
  const int shift = 8 * (8 - n);
  t = (t << (shift >> 1)) << (shift - (shift >> 1));
  return EightDigits(t);
}

// The number token [s, e) whose first '.' is at d (d == e: none), from the window masks: the
// integer digits and the fraction digits are read as independent 8-byte loads and combined
// without data-dependent branches (the digit counts and signs of real dumps vary from value to
// value, and a mispredicted branch costs more than the arithmetic). True with *out for [-]I[.F]
// with I of at most 8 and F of at most 16 digits, I*10^|F| + F <= 2^53; false for anything else
// (an exponent, a '+', junk): the caller tries SwarDouble.
inline bool DottedDouble(const char* s, const char* e, const char* d, double* out) {
  const bool neg = *s == '-';
  const char* b = s + neg;
  const int i = static_cast<int>(d - b);  // integer digits
  const int f = d == e ? 0 : static_cast<int>(e - d - 1);
  if (static_cast<unsigned>(i) > 8 || f > 16 || i + f == 0 || i + f > 19) return false;
  const int fy = f < 8 ? f : 8;  // fraction digits in the first load, and in the second
  const int fz = f - fy;
  const uint64_t x = (Load64(b) ^ kBytes('0')) & kLowMask[i];
  const uint64_t y = (Load64(d + 1) ^ kBytes('0')) & kLowMask[fy];
  const uint64_t z = (Load64(d + 9) ^ kBytes('0')) & kLowMask[fz];
  if ((NonDigits(x) | NonDigits(y) | NonDigits(z)) != 0) return false;
  const uint64_t mant = FirstDigits(x, i) * kPow10U64[f] + FirstDigits(y, fy) * kPow10U64[fz] + FirstDigits(z, fz);
  if (mant > kTwoTo53) return false;
  // Clinger's fast path (exact), the sign set as a bit.
  double v = static_cast<double>(mant) / kPow10[f];
  uint64_t bits;
  std::memcpy(&bits, &v, sizeof bits);
  bits |= static_cast<uint64_t>(neg) << 63;
  std::memcpy(out, &bits, sizeof bits);
  return true;
}

// --- header lines ------------------------------------------------------------------------------

// A non-negative integer line ("123\n"): the end of the line after its '\n', or nullptr.
inline const char* ScanCountLine(const char* p, int64_t* out) {
  const char* start = p;
  int64_t v = 0;
  while (IsDigit(*p) && p - start < 18) v = v * 10 + (*p++ - '0');
  if (p == start || *p != '\n') return nullptr;
  *out = v;
  return p + 1;
}

inline bool HasPrefix(const char* p, const char* end, std::string_view text) {
  return static_cast<size_t>(end - p) >= text.size() && std::memcmp(p, text.data(), text.size()) == 0;
}

inline bool ParseInt(std::string_view tok, int64_t* out) {
  if (tok.empty()) return false;
  auto [ptr, ec] = std::from_chars(tok.data(), tok.data() + tok.size(), *out);
  return ec == std::errc() && ptr == tok.data() + tok.size();
}

std::string Shorten(std::string_view s) {
  constexpr size_t kMax = 60;
  if (s.size() <= kMax) return std::string(s);
  return std::string(s.substr(0, kMax)) + "...";
}

constexpr std::string_view kItemAtoms = "ITEM: ATOMS";

}  // namespace

DumpColumns DumpFrame::Names(std::vector<std::string> names) {
  return std::make_shared<const std::vector<std::string>>(std::move(names));
}

int DumpFrame::Column(std::string_view name) const {
  for (size_t i = 0; i < num_columns(); ++i) {
    if ((*columns)[i] == name) return static_cast<int>(i);
  }
  return -1;
}

int DumpFrameView::Column(std::string_view name) const {
  for (size_t i = 0; i < num_columns(); ++i) {
    if ((**names)[i] == name) return static_cast<int>(i);
  }
  return -1;
}

DumpFrame DumpFrameView::ToFrame() const {
  DumpFrame f;
  f.step = step;
  f.atoms = atoms;
  if (names != nullptr) f.columns = *names;
  if (atoms > 0) f.values.assign(values, values + static_cast<size_t>(atoms) * num_columns());
  return f;
}

Status DumpReader::Error(const std::string& what) const {
  return Status::Corruption("dump line " + std::to_string(line_) + ": " + what);
}

Status DumpReader::Feed(std::string_view chunk, DumpFrameSink& sink) {
  if (!status_.ok()) return status_;
  struct SinkScope {
    DumpReader* r;
    ~SinkScope() { r->sink_ = nullptr; }
  } scope{this};
  sink_ = &sink;
  bytes_fed_ += chunk.size();
  // Finish the line carried over from the previous chunk first.
  if (!pending_.empty()) {
    const char* nl = static_cast<const char*>(std::memchr(chunk.data(), '\n', chunk.size()));
    if (nl == nullptr) {
      pending_.append(chunk);
      return Status::Ok();
    }
    size_t n = nl - chunk.data() + 1;
    pending_.append(chunk.substr(0, n));
    chunk.remove_prefix(n);
    std::string line = std::move(pending_);
    pending_.clear();
    status_ = ParseLines(line.data(), line.data() + line.size());
    if (!status_.ok()) return status_;
  }
  // Every complete line at once; the tail waits for the next chunk.
  const char* last = chunk.empty() ? nullptr : static_cast<const char*>(memrchr(chunk.data(), '\n', chunk.size()));
  size_t complete = last == nullptr ? 0 : last - chunk.data() + 1;
  if (complete > 0) {
    status_ = ParseLines(chunk.data(), chunk.data() + complete);
    if (!status_.ok()) return status_;
  }
  pending_.assign(chunk.substr(complete));
  return Status::Ok();
}

Status DumpReader::ParseLines(const char* p, const char* end) {
  while (p < end) {
    const char* q = state_ == State::kAtoms ? FastAtomLines(p, end) : FastHeaderLine(p, end);
    if (q != p) {
      p = q;
      continue;
    }
    // The general path, one line.
    const char* nl = static_cast<const char*>(std::memchr(p, '\n', end - p));
    ++line_;
    Status s = ParseLine(std::string_view(p, nl - p));
    if (!s.ok()) return s;
    p = nl + 1;
  }
  return Status::Ok();
}

const char* DumpReader::FastHeaderLine(const char* p, const char* end) {
  // Line after line of the header while each is plain; returns at the first that is not (left
  // to ParseLine), at the end of the text, or once the ATOMS line is read.
  while (p < end) {
    const char* q = nullptr;
    switch (state_) {
      case State::kItemTimestep:
        if (!HasPrefix(p, end, "ITEM: TIMESTEP\n")) return p;
        frame_ = Header();
        state_ = State::kTimestep;
        q = p + 15;
        break;
      case State::kTimestep:
        q = ScanCountLine(p, &frame_.step);
        if (q == nullptr) return p;
        state_ = State::kItemNumber;
        break;
      case State::kItemNumber:
        if (!HasPrefix(p, end, "ITEM: NUMBER OF ATOMS\n")) return p;
        state_ = State::kNumber;
        q = p + 22;
        break;
      case State::kNumber:
        q = ScanCountLine(p, &frame_.atoms);
        if (q == nullptr) return p;
        state_ = State::kItemBox;
        break;
      case State::kItemBox:
        // The box and ATOMS lines of most frames repeat the last frame's byte for byte.
        if (!tail_text_.empty() && HasPrefix(p, end, tail_text_)) {
          line_ += 5;
          StartAtoms();
          return p + tail_text_.size();
        }
        if (!HasPrefix(p, end, "ITEM: BOX BOUNDS")) return p;
        q = p + 16;
        while (*q != '\n') ++q;
        ++q;
        box_lines_ = 0;
        state_ = State::kBox;
        tail_build_.assign(p, q);
        break;
      case State::kBox: {
        q = p;
        int n = 0;
        double v;
        for (;;) {
          while (*q == ' ' || *q == '\t') ++q;
          if (*q == '\n' || *q == '\r') break;
          q = ScanDouble(q, &v);
          if (q == nullptr || !(IsSpace(*q) || *q == '\n')) return p;
          ++n;
        }
        while (IsSpace(*q)) ++q;
        if (*q != '\n' || (n != 2 && n != 3)) return p;
        ++q;
        if (++box_lines_ == 3) state_ = State::kItemAtoms;
        tail_build_.append(p, q);
        break;
      }
      case State::kItemAtoms: {
        if (atoms_line_.empty() || !HasPrefix(p, end, kItemAtoms) ||
            !HasPrefix(p + kItemAtoms.size(), end, atoms_line_)) {
          return p;
        }
        q = p + kItemAtoms.size() + atoms_line_.size();
        ++line_;
        tail_build_.append(p, q);
        tail_text_.swap(tail_build_);
        StartAtoms();
        return q;
      }
      case State::kAtoms:
        return p;
    }
    ++line_;
    p = q;
  }
  return p;
}

void DumpReader::StartAtoms() {
  ncol_ = names_->size();
  constexpr int64_t kMaxPresized = int64_t{1} << 22;  // values; more are added as lines arrive
  const size_t want = static_cast<size_t>(std::min(frame_.atoms, kMaxPresized / static_cast<int64_t>(ncol_))) * ncol_;
  if (want > values_cap_) Grow(want, 0);
  atoms_read_ = 0;
  state_ = State::kAtoms;
  if (frame_.atoms == 0) FinishFrame();
}

void DumpReader::FinishFrame() {
  state_ = State::kItemTimestep;
  DumpFrameView view;
  view.step = frame_.step;
  view.atoms = frame_.atoms;
  view.names = &names_;
  view.columns_serial = names_serial_;
  view.values = values_.get();
  sink_->OnFrame(view);
}

void DumpReader::Grow(size_t need, size_t keep) {
  size_t grown = std::max(need, 2 * values_cap_);
  size_t total;
  if (!__builtin_mul_overflow(static_cast<size_t>(frame_.atoms), ncol_, &total))
    grown = std::min(grown, std::max(total, need));
  // Not value-initialized: zero-filling would cost a pass over memory every value overwrites.
  std::unique_ptr<double[]> bigger(new double[grown]);
  if (keep > 0) std::memcpy(bigger.get(), values_.get(), keep * sizeof(double));
  values_ = std::move(bigger);
  values_cap_ = grown;
}

// Atom lines, tokens found 64 bytes at a time: the blank mask of a 64-byte window gives where
// each number starts and ends, so the numbers of a line are parsed independently of each other.
// Any line that is not plain (a '+' sign, a long number, a missing value, junk) is left to the
// general path, from its start.
const char* DumpReader::FastAtomLines(const char* p, const char* end) {
  constexpr ptrdiff_t kReadable = 64 + 32;  // a window plus what SwarDouble may read past it
  const size_t ncol = ncol_;
  const char* line = p;  // start of the current line
  size_t col = 0;
  double* out = Row(atoms_read_);
  const char* gap = p;  // end of the last token (or the line start)
  const char* w = p;    // window base
  while (end - w >= kReadable) {
    uint64_t blank, dots;
    Masks64(w, &blank, &dots);
    uint64_t token = ~blank;
    while (token != 0) {
      int s = __builtin_ctzll(token);
      uint64_t after = blank & (~uint64_t{0} << s);
      if (after == 0) break;  // the token runs past the window
      int e = __builtin_ctzll(after);
      const char* ts = w + s;
      // The blanks before the token: one ' ' between values; only spaces before a line's first.
      if (col == 0) {
        for (const char* g = gap; g < ts; ++g) {
          if (*g != ' ' && *g != '\t') return line;
        }
      } else if (ts - gap != 1 || *gap != ' ') {
        for (const char* g = gap; g < ts; ++g) {
          if (*g != ' ' && *g != '\t') return line;
        }
      }
      const uint64_t dot_after = dots & (~uint64_t{0} << s);
      const char* te = w + e;
      const char* d = dot_after == 0 ? te : std::min(te, w + __builtin_ctzll(dot_after));
      if (!DottedDouble(ts, te, d, out + col) && !SwarDouble(ts, te, out + col)) return line;
      gap = w + e;
      if (++col == ncol) {
        // The line must end here (trailing blanks allowed).
        const char* q = gap;
        while (IsSpace(*q)) ++q;
        if (*q != '\n') return line;
        ++line_;
        line = gap = q + 1;
        col = 0;
        if (++atoms_read_ == frame_.atoms) {
          FinishFrame();
          return line;
        }
        out = Row(atoms_read_);
        if (line >= w + 64) break;
        token &= ~uint64_t{0} << (line - w);
        continue;
      }
      token &= ~uint64_t{0} << e;
    }
    // Next window: from the first token not finished in this one, or after this window.
    const char* next = w + 64;
    if (token != 0) next = w + __builtin_ctzll(token);
    if (gap > next) next = gap;
    if (next == w) return line;  // a token of 64 or more bytes
    w = next;
  }
  return line;
}

Status DumpReader::ParseLine(std::string_view line) {
  switch (state_) {
    case State::kItemTimestep: {
      std::string_view t = Trim(line);
      if (t.empty()) return Status::Ok();  // tolerate blank lines between frames
      if (t != "ITEM: TIMESTEP") return Error("expected 'ITEM: TIMESTEP', got '" + Shorten(t) + "'");
      frame_ = Header();
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
      tail_build_.assign(line);
      tail_build_.push_back('\n');
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
      tail_build_.append(line);
      tail_build_.push_back('\n');
      return Status::Ok();
    }
    case State::kItemAtoms: {
      std::string_view t = Trim(line);
      if (!StartsWith(t, kItemAtoms)) return Error("expected 'ITEM: ATOMS', got '" + Shorten(t) + "'");
      std::string_view rest = t.substr(kItemAtoms.size());
      if (!rest.empty() && !IsSpace(rest.front())) {
        return Error("expected 'ITEM: ATOMS', got '" + Shorten(t) + "'");
      }
      std::vector<std::string> names;
      size_t pos = 0;
      for (std::string_view tok = NextToken(rest, &pos); !tok.empty(); tok = NextToken(rest, &pos)) {
        names.emplace_back(tok);
      }
      if (names.empty()) return Error("'ITEM: ATOMS' names no columns");
      if (names_ == nullptr || *names_ != names) {
        names_ = DumpFrame::Names(std::move(names));
        ++names_serial_;
      }
      // Later frames with this very line take the fast path (FastHeaderLine).
      if (StartsWith(line, kItemAtoms) && IsSpace(line[kItemAtoms.size()])) {
        atoms_line_.assign(line.substr(kItemAtoms.size()));
        atoms_line_.push_back('\n');
      } else {
        atoms_line_.clear();
      }
      tail_build_.append(line);
      tail_build_.push_back('\n');
      tail_text_.swap(tail_build_);
      StartAtoms();
      return Status::Ok();
    }
    case State::kAtoms: {
      const char* p = line.data();
      const char* end = p + line.size();
      const size_t ncol = ncol_;
      double* out = Row(atoms_read_);
      for (size_t c = 0; c < ncol; ++c) {
        while (p < end && IsSpace(*p)) ++p;
        const char* tok_end = p;
        while (tok_end < end && !IsSpace(*tok_end)) ++tok_end;
        std::string_view tok(p, tok_end - p);
        if (tok.empty()) {
          return Error("atom line has " + std::to_string(c) + " values, expected " + std::to_string(ncol));
        }
        // The line ends in '\n' in the reader's buffer, the sentinel ScanDouble needs.
        const char* q = ScanDouble(p, &out[c]);
        if (q != tok_end && !ParseDouble(tok, &out[c])) {
          return Error("column '" + (*names_)[c] + "': '" + Shorten(tok) + "' is not a number");
        }
        p = tok_end;
      }
      while (p < end && IsSpace(*p)) ++p;
      if (p != end) return Error("atom line has more than " + std::to_string(ncol) + " values");
      if (++atoms_read_ == frame_.atoms) FinishFrame();
      return Status::Ok();
    }
  }
  return Status::Internal("unreachable dump reader state");
}

Status DumpReader::Finish() { return status_; }

Result<std::vector<DumpFrame>> ReadDump(std::string_view text) {
  DumpReader reader;
  DumpFrameCollector frames;
  Status s = reader.Feed(text, frames);
  if (!s.ok()) return s;
  return frames.Take();
}

Status ReadDump(std::string_view text, DumpFrameSink& sink) {
  DumpReader reader;
  return reader.Feed(text, sink);
}

}  // namespace sandswim
