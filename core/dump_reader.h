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
// Ownership: the reader owns a copy of at most one partial frame's text. Frames are values.
// Thread safety: none; one reader per stream.
#ifndef SANDSWIM_CORE_DUMP_READER_H_
#define SANDSWIM_CORE_DUMP_READER_H_

#include <cstddef>
#include <cstdint>
#include <deque>
#include <string>
#include <string_view>
#include <vector>

#include "core/status.h"

namespace sandswim {

struct DumpFrame {
  int64_t step = 0;
  std::vector<std::string> columns;  // names from the ITEM: ATOMS line, e.g. "id", "x", ...
  int64_t atoms = 0;
  std::vector<double> values;        // atoms x columns, row-major (atom i, column c)

  // Index of a named column, or -1.
  int Column(std::string_view name) const;
  double At(int64_t atom, int column) const { return values[atom * columns.size() + column]; }
};

class DumpReader {
 public:
  DumpReader() = default;

  // Parses as much of the text seen so far as forms complete lines. Complete frames are queued
  // for TakeFrames(). Returns Corruption ("dump line N: ...") on text that is not a dump.
  Status Feed(std::string_view chunk);

  // Moves out the frames completed so far, oldest first.
  std::vector<DumpFrame> TakeFrames();

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

  Status ParseLine(std::string_view line);
  Status Error(const std::string& what) const;

  State state_ = State::kItemTimestep;
  std::string pending_;  // an incomplete line carried over between chunks
  DumpFrame frame_;      // the frame being read
  int box_lines_ = 0;
  int64_t atoms_read_ = 0;
  int64_t line_ = 0;
  uint64_t bytes_fed_ = 0;
  Status status_;
  std::deque<DumpFrame> done_;
};

// Convenience: every complete frame of a whole dump text (a torn last frame is dropped).
Result<std::vector<DumpFrame>> ReadDump(std::string_view text);

}  // namespace sandswim

#endif  // SANDSWIM_CORE_DUMP_READER_H_
