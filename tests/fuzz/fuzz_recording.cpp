// libFuzzer target: the recording reader (read_recording) on any bytes as a file.
//
// Oracles: the reader returns or throws RecordingError, nothing else (no crash, no hang, no
// other exception); a refusal names the file and says why; a recording it returns is one the
// format allows: named, distinct columns, every column as long as the others, values finite or
// NaN (a missing field), time present and never decreasing, format mls-recording/1 if stated.
#include <cmath>

#include "fuzz_common.hpp"
#include "maglead/recording/recording.hpp"

namespace {

constexpr std::string_view kTarget = "fuzz_recording";

void check(bool cond, std::string_view what) {
  if (!cond) maglead::fuzz::oracle_failed(kTarget, what);
}

void check_recording(const maglead::Recording& rec) {
  check(!rec.names.empty() && rec.columns.size() == rec.names.size(), "columns and names differ");
  for (std::size_t i = 0; i < rec.names.size(); ++i) {
    check(!rec.names[i].empty(), "a column without a name");
    for (std::size_t j = 0; j < i; ++j) check(rec.names[j] != rec.names[i], "a column twice");
    check(rec.columns[i].size() == rec.rows(), "columns of different lengths");
    for (const double v : rec.columns[i]) check(!std::isinf(v), "an infinite value");
  }
  if (const auto fmt = rec.meta("format")) check(*fmt == "mls-recording/1", "a foreign format");
  if (!rec.has("t_s")) return;
  const std::vector<double>& t = rec.column("t_s");
  for (std::size_t i = 0; i < t.size(); ++i) {
    check(!std::isnan(t[i]), "a row without time");
    check(i == 0 || t[i] >= t[i - 1], "time decreases");
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = maglead::fuzz::write_input(data, size, ".csv");
  try {
    check_recording(maglead::read_recording(path));
  } catch (const maglead::RecordingError& e) {
    maglead::fuzz::check_refusal(kTarget, e, path);
  }
  return 0;
}
