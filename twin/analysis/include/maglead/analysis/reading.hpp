#pragma once
// What analyze_recording reads of a recording and what it refuses, before any fit: the readers
// store only its columns, and `inspect` runs its checks to say what `analyze` would refuse.
#include <string>
#include <vector>

#include "maglead/recording/recording.hpp"

namespace maglead::analysis {

/// The columns analyze_recording may read of a recording with this header (names, metadata; no
/// rows needed): a reader stores only these (read_recording's ColumnChoice).
std::vector<std::string> columns_read(const Recording& header);

/// The analysis's own check of an axis's recording (a `# axis:` line or an axis kind's columns),
/// its model unknown: the kind named, its columns and t_s there, else the refusal analyze gives
/// (std::invalid_argument or RecordingError, saying what to fix). `inspect` runs it. An
/// actuator's recording passes: its columns are its reader's to check.
void check_axis_columns(const Recording& rec);

/// What the analysis of a force-driven axis needs of the rows before any fit, refused as it
/// refuses them: t_s, the kind's position and drive (`# axis:`; none: linear) with a value in
/// every row and rules::kMinRows rows (RecordingError, std::invalid_argument), and a sample rate
/// of rules::kAxisMinRateHz or more, saying what to fix (t_s in milliseconds: divide by 1000).
/// Missing columns are check_axis_columns' to refuse: this passes them. `inspect` and `analyze`
/// run it.
void check_axis_rows(const Recording& rec);

/// The actuator's alike: t_s, nut_pos_m and load_force_n with a value in every row, and
/// rules::kMinRows rows (its position filter follows the rate: no rate is refused).
void check_actuator_rows(const Recording& rec);

}  // namespace maglead::analysis
