// DumpReader: a streaming parser of LIGGGHTS/LAMMPS `dump custom` text.
//
// A dump is a sequence of frames:
//   ITEM: TIMESTEP
//   <step>
//   ITEM: NUMBER OF ATOMS
//   <n>
//   ITEM: BOX BOUNDS <flags>
//   <lo> <hi> [tilt]      (three lines)
//   ITEM: ATOMS <col> <col> ...
//   <n lines of numbers, one per atom>
// The reader takes the text in chunks of any size (a file being tailed while the engine writes it,
// or a whole file at once) and emits each frame as soon as its last atom line is complete. A frame
// whose text is cut anywhere (the engine is still writing it, or the file was truncated) is held
// back and never emitted: Finish() reports it as torn. A line that does not fit the format
// makes Feed() return Status Corruption naming the line number and what was expected; the
// reader then stays in that error state.
//
// Numbers are read exactly as std::from_chars reads them (bit-identical doubles); a leading '+',
// denormals and exponents are accepted. Lines may end in "\r\n" and carry trailing blanks; blank
// lines between frames are skipped.
//
// Frames come out through a sink: Feed(chunk, sink) hands each complete frame to sink.OnFrame() as
// a DumpFrameView the moment its last atom line is parsed, before Feed returns, in order, exactly
// once. Nothing is allocated per frame: the view's values live in one buffer the reader reuses
// frame after frame (valid only during the call; copy what you keep). DumpFrameCollector keeps
// copies (DumpFrame values); ReadDump() reads a whole text either way.
//
// Speed: the common case (complete lines in a large chunk) is parsed without splitting lines and
// with an 8-byte-at-a-time number parser; a frame header whose text equals the previous frame's
// (box bounds, ATOMS line) is matched with memcmp instead of re-parsed.
// tests/bench/bench_dump_parse.cc measures it against `wc -l`. Column names are parsed once per
// distinct ITEM: ATOMS line and shared by the frames.
//
// Ownership: the reader owns a copy of at most one partial line's text and a values buffer of
// the largest frame seen (atoms x columns doubles, grown as atom lines arrive). Frames are values
// (their column-name list is immutable and shared).
// Thread safety: none; one reader per stream.
#ifndef SANDSWIM_CORE_DUMP_READER_H_
#define SANDSWIM_CORE_DUMP_READER_H_

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "core/status.h"

namespace sandswim {

using DumpColumns = std::shared_ptr<const std::vector<std::string>>;

struct DumpFrame {
  int64_t step = 0;
  // Names from the ITEM: ATOMS line, e.g. "id", "x", ...; never null in a frame the reader made.
  // Shared by every frame read with the same ATOMS line.
  DumpColumns columns;
  int64_t atoms = 0;
  std::vector<double> values;  // atoms x columns, row-major (atom i, column c)

  // A column-name list for `columns` (for frames made by hand, e.g. in tests).
  static DumpColumns Names(std::vector<std::string> names);

  size_t num_columns() const { return columns ? columns->size() : 0; }
  // Index of a named column, or -1.
  int Column(std::string_view name) const;
  double At(int64_t atom, int column) const { return values[atom * num_columns() + column]; }
};

// A complete frame, lent to a DumpFrameSink for the duration of one OnFrame() call.
struct DumpFrameView {
  int64_t step = 0;
  int64_t atoms = 0;
  // The frame's column-name list (never null in a view the reader made); the same object for
  // every frame read with the same ATOMS line.
  const DumpColumns* names = nullptr;
  // Changes exactly when the column list changes (a distinct ATOMS line): a sink may cache
  // column indices while it stays the same.
  uint64_t columns_serial = 0;
  const double* values = nullptr;  // atoms x columns, row-major; owned by the reader

  const std::vector<std::string>& columns() const { return **names; }
  size_t num_columns() const { return names != nullptr && *names != nullptr ? (*names)->size() : 0; }
  // Index of a named column, or -1.
  int Column(std::string_view name) const;
  double At(int64_t atom, int column) const { return values[atom * num_columns() + column]; }
  // A copy that outlives the call.
  DumpFrame ToFrame() const;
};

class DumpFrameSink {
 public:
  virtual ~DumpFrameSink() = default;
  // Called once per complete frame, oldest first, from inside DumpReader::Feed.
  virtual void OnFrame(const DumpFrameView& frame) = 0;
};

// A DumpFrameSink that calls a function (a lambda) on each frame.
template <typename Fn>
class DumpFrameFn final : public DumpFrameSink {
 public:
  explicit DumpFrameFn(Fn fn) : fn_(std::move(fn)) {}
  void OnFrame(const DumpFrameView& frame) override { fn_(frame); }

 private:
  Fn fn_;
};

// A DumpFrameSink that keeps a copy of every frame (ReadDump(text), tests, tools).
class DumpFrameCollector final : public DumpFrameSink {
 public:
  void OnFrame(const DumpFrameView& frame) override { frames_.push_back(frame.ToFrame()); }
  // Moves out the frames collected so far, oldest first.
  std::vector<DumpFrame> Take() { return std::exchange(frames_, {}); }

 private:
  std::vector<DumpFrame> frames_;
};

class DumpReader {
 public:
  DumpReader() = default;

  // Parses as much of the text seen so far as forms complete lines, handing each frame completed
  // to sink.OnFrame() (oldest first) before returning. Returns Corruption ("dump line N: ...")
  // on text that is not a dump; frames completed before the bad line were delivered.
  Status Feed(std::string_view chunk, DumpFrameSink& sink);

  // Declares the end of the input. OK whether or not a torn frame was held back (it is dropped);
  // torn() then says whether one was. Returns the error state if Feed() failed before.
  Status Finish();

  // True when text after the last complete frame was seen (a frame still being written).
  bool torn() const { return state_ != State::kItemTimestep || !pending_.empty(); }
  // Bytes fed so far, lines completed so far.
  uint64_t bytes_fed() const { return bytes_fed_; }
  int64_t lines() const { return line_; }
  const Status& status() const { return status_; }

 private:
  enum class State { kItemTimestep, kTimestep, kItemNumber, kNumber, kItemBox, kBox, kItemAtoms, kAtoms };

  struct Header {
    int64_t step = 0;
    int64_t atoms = 0;
  };

  // Parses the complete lines of [p, end); end[-1] is '\n'.
  Status ParseLines(const char* p, const char* end);
  // The fast path for the lines of the current state: returns where it stopped (at a line start),
  // which is `p` when the next line needs the general ParseLine (an odd line or an error).
  const char* FastHeaderLine(const char* p, const char* end);
  const char* FastAtomLines(const char* p, const char* end);
  Status ParseLine(std::string_view line);
  Status Error(const std::string& what) const;
  void StartAtoms();
  void FinishFrame();
  // Makes room for atom row `row` in values_ (not zero-filled: every value is written before the
  // frame is delivered).
  double* Row(int64_t row) {
    size_t need = static_cast<size_t>(row + 1) * ncol_;
    if (need > values_cap_) Grow(need, static_cast<size_t>(row) * ncol_);
    return values_.get() + static_cast<size_t>(row) * ncol_;
  }
  // Grows values_ to hold at least `need` values, keeping the first `keep`.
  void Grow(size_t need, size_t keep);

  State state_ = State::kItemTimestep;
  std::string pending_;               // an incomplete line carried over between chunks
  Header frame_;                      // the frame being read
  std::unique_ptr<double[]> values_;  // its values, reused by every frame
  size_t values_cap_ = 0;
  size_t ncol_ = 0;         // names_->size() once the ATOMS line is read
  std::string atoms_line_;  // text after "ITEM: ATOMS" of the last ATOMS line, with its '\n'
  DumpColumns names_;       // the names parsed from atoms_line_
  uint64_t names_serial_ = 0;
  // The text from "ITEM: BOX BOUNDS" through the ATOMS line's '\n' (5 lines) of the last frame
  // whose lines were checked one by one (so valid, and the source of names_); empty when unknown.
  std::string tail_text_;
  std::string tail_build_;     // the same, being collected for the current frame
  bool tail_matched_ = false;  // the current frame's tail was matched against tail_text_
  int box_lines_ = 0;
  int64_t atoms_read_ = 0;
  int64_t line_ = 0;
  uint64_t bytes_fed_ = 0;
  Status status_;
  DumpFrameSink* sink_ = nullptr;  // during Feed
};

// Convenience: every complete frame of a whole dump text (a torn last frame is dropped).
Result<std::vector<DumpFrame>> ReadDump(std::string_view text);
// The same, each frame handed to `sink`; returns the reader's status.
Status ReadDump(std::string_view text, DumpFrameSink& sink);

}  // namespace sandswim

#endif  // SANDSWIM_CORE_DUMP_READER_H_
