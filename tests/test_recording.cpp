// The mls-recording/1 reader: round trip, and errors that name the file, line and column.
#include <gtest/gtest.h>

#include "test_tmp.hpp"

#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <limits>
#include <random>
#include <tuple>
#include <vector>

#include "maglead/recording/error_stats.hpp"
#include "maglead/recording/recording.hpp"

using namespace maglead;

namespace {
std::string write_file(const std::string& name, const std::string& text) {
  std::string path = test_tmp_dir() + "/" + name;
  std::ofstream(path) << text;
  return path;
}
std::string error_of(const std::string& path, const std::vector<std::string>& required = {}) {
  try {
    read_recording(path, required);
  } catch (const RecordingError& e) {
    return e.what();
  }
  return "";
}
}  // namespace

TEST(Recording, RoundTripKeepsMetadataColumnsAndMissingValues) {
  Recording r;
  r.metadata = {{"sample_rate_hz", "1000"}, {"source", "test: with colon"}};
  r.add_column("t_s", {0.0, 0.001, 0.002});
  r.add_column("nut_pos_m", {1e-5, NAN, 3.25e-5});
  const std::string path = test_tmp_dir() + "/rt.csv";
  write_recording(path, r);
  const Recording b = read_recording(path, {"t_s", "nut_pos_m"});
  EXPECT_EQ(b.meta("format"), "mls-recording/1");
  EXPECT_EQ(b.meta("source"), "test: with colon");
  ASSERT_EQ(b.rows(), 3u);
  EXPECT_DOUBLE_EQ(b.column("nut_pos_m")[2], 3.25e-5);
  EXPECT_TRUE(std::isnan(b.column("nut_pos_m")[1]));
}

TEST(Recording, UnknownColumnsAreKept) {
  const auto p = write_file("extra.csv", "# format: mls-recording/1\nt_s,temp_c\n0,20.5\n1,21\n");
  const auto r = read_recording(p, {"t_s"});
  EXPECT_DOUBLE_EQ(r.column("temp_c")[1], 21.0);
}

TEST(Recording, MissingColumnNamesFileLineAndColumn) {
  const auto p = write_file("missing.csv", "# format: mls-recording/1\nt_s,nut_pos_m\n0,0\n");
  const std::string e = error_of(p, {"t_s", "load_force_n"});
  EXPECT_NE(e.find("missing.csv:2"), std::string::npos) << e;
  EXPECT_NE(e.find("load_force_n"), std::string::npos) << e;
}

// A column in another unit (or none) is named with what to do; every missing column lists the
// columns there are, and says which one it is to the caller (MissingColumnError::column).
TEST(Recording, MissingColumnListsTheColumnsAndOneInAnotherUnit) {
  const auto mm = write_file("mm.csv", "# format: mls-recording/1\nt_s,nut_pos_mm\n0,0\n");
  const std::string e = error_of(mm, {"t_s", "nut_pos_m"});
  EXPECT_NE(e.find("(header has: t_s, nut_pos_mm)"), std::string::npos) << e;
  EXPECT_NE(e.find("'nut_pos_mm' looks like nut_pos_m in another unit: convert it to metres and "
                   "name it 'nut_pos_m'"),
            std::string::npos)
      << e;
  const auto bare = write_file("bare.csv", "# format: mls-recording/1\nt_s,load_force\n0,0\n");
  EXPECT_NE(error_of(bare, {"load_force_n"})
                .find("'load_force' has no unit in its name: if it is in newtons, name it "
                      "'load_force_n'"),
            std::string::npos);
  try {
    read_recording(mm, {"t_s"}).column("nut_pos_m");
    ADD_FAILURE() << "column() of a missing column returned";
  } catch (const MissingColumnError& c) {
    EXPECT_EQ(c.column(), "nut_pos_m");
    EXPECT_NE(std::string(c.what()).find("(columns read: t_s, nut_pos_mm); 'nut_pos_mm' looks"),
              std::string::npos)
        << c.what();
  }
  // A compound unit with a prefix is the same quantity: millinewton metres, millimetres per second.
  EXPECT_NE(missing_column_detail({"t_s", "drive_torque_mn_m"}, "drive_torque_n_m")
                .find("'drive_torque_mn_m' looks like drive_torque_n_m in another unit: convert it "
                      "to newton metres"),
            std::string::npos);
  EXPECT_NE(missing_column_detail({"nut_vel_mm_s"}, "nut_vel_m_s").find("looks like nut_vel_m_s"),
            std::string::npos);
  // Same quantity, unrelated name: no advice to rename what is something else.
  const auto other = write_file("other.csv", "# format: mls-recording/1\nt_s,pos_set_m\n0,0\n");
  EXPECT_EQ(error_of(other, {"nut_pos_m"}).find("looks like"), std::string::npos);
}

// The walkthrough's headers: upper case is not another unit, quotes are no part of a name (R's
// write.csv), and a reader that stores only some columns keeps one that stands in for a missing
// one, so its error names it (analyze on t_s,pos_mm,drive_force_n listed t_s, drive_force_n).
TEST(Recording, UpperCaseQuotedAndStandInColumnsAreNamedWithTheFix) {
  EXPECT_EQ(missing_column_detail({"T_S", "POS_M"}, "t_s"),
            " (header has: T_S, POS_M); column names are lower case: rename 'T_S' to 't_s'");
  EXPECT_EQ(stand_in_hint("screw_angle_deg", "screw_angle_rad"),
            "'screw_angle_deg' looks like screw_angle_rad in another unit: convert it to radians "
            "and name it 'screw_angle_rad' (units are SI: docs/recording-format.md)");
  const auto quoted =
      write_file("quoted.csv", "# format: mls-recording/1\n\"t_s\", \"x_m\"\n0,1\n0.001,2\n");
  EXPECT_EQ(read_recording(quoted, {"t_s", "x_m"}).names, (std::vector<std::string>{"t_s", "x_m"}));
  const auto mm = write_file(
      "stand_in.csv", "# format: mls-recording/1\nt_s,pos_mm,drive_force_n,other_v\n0,1,2,3\n");
  const Recording r = read_recording(mm, {}, [](const Recording&) {
    return std::vector<std::string>{"t_s", "pos_m", "drive_force_n"};
  });
  EXPECT_EQ(r.names, (std::vector<std::string>{"t_s", "pos_mm", "drive_force_n"}));
  const auto na = write_file("na.csv", "# format: mls-recording/1\nt_s,x_m\n0,NA\n");
  EXPECT_NE(error_of(na).find("'NA' is not a number: a missing value is an empty field"),
            std::string::npos)
      << error_of(na);
}

TEST(Recording, NonNumericFieldNamesLineAndColumn) {
  const auto p =
      write_file("nan.csv", "# format: mls-recording/1\nt_s,nut_pos_m\n0,0\n0.001,abc\n");
  const std::string e = error_of(p);
  EXPECT_NE(e.find("nan.csv:4"), std::string::npos) << e;
  EXPECT_NE(e.find("column 2 (nut_pos_m)"), std::string::npos) << e;
  EXPECT_NE(e.find("'abc'"), std::string::npos) << e;
}

TEST(Recording, ColumnsNotKeptAreCheckedButNotStored) {
  const std::string head = "# format: mls-recording/1\n# axis: linear\nt_s,a_m,b_n,c_rad\n";
  const std::string rows = "0,1,2,3\n0.001,4,5,6\n";
  const auto keep_a = [](const Recording& header) {
    EXPECT_EQ(header.meta("axis"), "linear");  // the chooser sees the metadata …
    EXPECT_EQ(header.names.size(), 4u);        // … and every name
    return std::vector<std::string>{"a_m", "not_in_the_file"};
  };
  const Recording r = read_recording(write_file("keep.csv", head + rows), {"c_rad"}, keep_a);
  EXPECT_EQ(r.names, (std::vector<std::string>{"a_m", "c_rad"}));  // required ones are stored
  ASSERT_EQ(r.columns.size(), 2u);
  EXPECT_EQ(r.rows(), 2u);
  EXPECT_FALSE(r.has("b_n"));
  EXPECT_FALSE(r.has("t_s"));
  EXPECT_DOUBLE_EQ(r.column("a_m")[1], 4.0);
  EXPECT_DOUBLE_EQ(r.column("c_rad")[1], 6.0);

  // A required column is required whatever is kept.
  const auto p = write_file("keep_missing.csv", head + rows);
  try {
    read_recording(p, {"d_n"}, keep_a);
    ADD_FAILURE() << "no error";
  } catch (const RecordingError& e) {
    EXPECT_EQ(std::string(e.what()), error_of(p, {"d_n"}));
  }

  // A skipped column's malformed value, a ragged row naming a skipped column and a decreasing
  // skipped t_s are the same errors, at the same line, as when every column is stored.
  for (const std::string bad : {"0.002,7,x8,9\n", "0.002,7\n", "0.0005,7,8,9\n"}) {
    const auto q = write_file("keep_bad.csv", head + rows + bad + "0.003,1,2,3\n");
    const std::string all = error_of(q);
    ASSERT_NE(all.find("keep_bad.csv:6: "), std::string::npos) << all;
    try {
      read_recording(q, {}, keep_a);
      ADD_FAILURE() << "no error for " << bad;
    } catch (const RecordingError& e) {
      EXPECT_EQ(std::string(e.what()), all);
    }
  }
}

TEST(Recording, DecreasingTimeIsAnError) {
  const auto p = write_file("back.csv", "t_s,x_m\n0,0\n0.002,0\n0.001,0\n");
  const std::string e = error_of(p);
  EXPECT_NE(e.find("back.csv:4"), std::string::npos) << e;
  EXPECT_NE(e.find("time decreases"), std::string::npos) << e;
}

TEST(Recording, RaggedRowsAndForeignFormatsAreErrors) {
  EXPECT_NE(error_of(write_file("short.csv", "t_s,a_m\n0\n")).find("short.csv:2"),
            std::string::npos);
  EXPECT_NE(error_of(write_file("long.csv", "t_s,a_m\n0,1,2\n")).find("more fields"),
            std::string::npos);
  EXPECT_NE(error_of(write_file("fmt.csv", "# format: other/2\nt_s\n0\n")).find("other/2"),
            std::string::npos);
  EXPECT_NE(error_of(test_tmp_dir() + "/does-not-exist.csv").find("cannot open"),
            std::string::npos);
}

namespace {
std::uint64_t bits(double v) { return std::bit_cast<std::uint64_t>(v); }

// Doubles of every kind a recording can hold: random bit patterns (all exponents, subnormals),
// ordinary magnitudes, small integers, signed zeros; NaN (missing) now and then.
double sample_value(std::mt19937_64& rng, std::size_t col) {
  switch (rng() % 6) {
    case 0: {
      double v;
      do {
        v = std::bit_cast<double>(rng());
      } while (!std::isfinite(v));
      return v;
    }
    case 1:
      return std::ldexp(static_cast<double>(rng() % 1000 + 1),
                        -1074 + static_cast<int>(rng() % 40));
    case 2:
      return static_cast<double>(static_cast<std::int64_t>(rng() % 2001) - 1000);
    case 3:
      return (rng() % 2 ? -0.0 : 0.0);
    case 4:
      return col > 1 && rng() % 4 == 0 ? NAN : std::uniform_real_distribution<double>(-5, 5)(rng);
    default:
      return std::normal_distribution<double>(0, 1e-3)(rng);
  }
}

void expect_same_bits(const Recording& a, const std::vector<std::vector<double>>& cols) {
  ASSERT_EQ(a.columns.size(), cols.size());
  for (std::size_t c = 0; c < cols.size(); ++c) {
    ASSERT_EQ(a.columns[c].size(), cols[c].size()) << "column " << c;
    for (std::size_t r = 0; r < cols[c].size(); ++r) {
      const double got = a.columns[c][r], want = cols[c][r];
      if (std::isnan(want))
        ASSERT_TRUE(std::isnan(got)) << "row " << r << " column " << c;
      else
        ASSERT_EQ(bits(got), bits(want))
            << "row " << r << " column " << c << ": " << got << " != " << want;
    }
  }
}
}  // namespace

// Tens of megabytes, so the reader crosses many read blocks; written by RecordingWriter
// (shortest round-trip, to_chars) and by hand with %.17g: both read back bit for bit.
TEST(Recording, LargeFileRoundTripIsBitExact) {
  std::mt19937_64 rng(20240610);
  const std::size_t rows = 200000, ncol = 6;
  // Any bit pattern: no column is a position or an angle, whose values must be plausible.
  std::vector<std::string> names = {"t_s", "x_a", "a_m", "b_n", "c_v", "d_a"};
  std::vector<std::vector<double>> cols(ncol, std::vector<double>(rows));
  double t = 0;
  for (std::size_t r = 0; r < rows; ++r) {
    t += 1e-3 * (1.0 + 1e-3 * static_cast<double>(rng() % 7));  // a recorder's jitter
    cols[0][r] = t;
    for (std::size_t c = 1; c < ncol; ++c) cols[c][r] = sample_value(rng, c);
  }

  const std::string shortest = test_tmp_dir() + "/large_to_chars.csv";
  {
    RecordingWriter w(shortest, {{"sample_rate_hz", "1000"}}, names);
    std::vector<double> row(ncol);
    for (std::size_t r = 0; r < rows; ++r) {
      for (std::size_t c = 0; c < ncol; ++c) row[c] = cols[c][r];
      w.write_row(row.data(), ncol);
    }
    w.close();
  }
  const Recording a = read_recording(shortest, {"t_s"});
  EXPECT_EQ(a.names, names);
  expect_same_bits(a, cols);

  const std::string g17 = test_tmp_dir() + "/large_g17.csv";
  {
    std::FILE* f = std::fopen(g17.c_str(), "w");
    ASSERT_NE(f, nullptr);
    std::fprintf(f, "# format: mls-recording/1\nt_s,x_a,a_m,b_n,c_v,d_a\n");
    for (std::size_t r = 0; r < rows; ++r)
      for (std::size_t c = 0; c < ncol; ++c) {
        if (!std::isnan(cols[c][r])) std::fprintf(f, "%.17g", cols[c][r]);
        std::fputc(c + 1 < ncol ? ',' : '\n', f);
      }
    ASSERT_EQ(std::fclose(f), 0);
  }
  expect_same_bits(read_recording(g17), cols);
}

// Every malformed input names the file, the line and the column (by number and name where
// there is one).
TEST(Recording, EveryErrorNamesFileLineAndColumn) {
  struct Case {
    const char* name;
    std::string text;
    std::vector<std::string> required;
    std::vector<std::string> expected;
  };
  const std::string head = "# format: mls-recording/1\nt_s,nut_pos_m,temp_c\n";
  const std::vector<Case> cases = {
      {"required",
       head + "0,1,2\n",
       {"t_s", "load_force_n"},
       {"required.csv:2: ", "'load_force_n'"}},
      {"word",
       head + "0,1,2\n0.001,abc,2\n",
       {},
       {"word.csv:4: ", "column 2 (nut_pos_m)", "'abc'"}},
      {"inf", head + "0,1,inf\n", {}, {"inf.csv:3: ", "column 3 (temp_c)", "'inf'"}},
      {"nantext", head + "0,nan,1\n", {}, {"nantext.csv:3: ", "column 2 (nut_pos_m)", "'nan'"}},
      {"range", head + "0,1e400,1\n", {}, {"range.csv:3: ", "column 2 (nut_pos_m)", "'1e400'"}},
      {"tail", head + "0,1.5x,1\n", {}, {"tail.csv:3: ", "column 2 (nut_pos_m)", "'1.5x'"}},
      {"sign", head + "0,1,--2\n", {}, {"sign.csv:3: ", "column 3 (temp_c)", "'--2'"}},
      {"inner", head + "0,1 2,3\n", {}, {"inner.csv:3: ", "column 2 (nut_pos_m)", "'1 2'"}},
      {"notime",
       head + "0,1,2\n,1,2\n",
       {},
       {"notime.csv:4: ", "column 1 (t_s)", "time is missing"}},
      {"back",
       head + "0,1,2\n0.002,1,2\n# note\n\n0.001,1,2\n",
       {},
       {"back.csv:7: ", "column 1 (t_s)", "time decreases (0.001 after 0.002)"}},
      {"noname",
       "# format: mls-recording/1\nt_s,,temp_c\n",
       {},
       {"noname.csv:2: ", "column 2 has no name"}},
      {"twice",
       "# format: mls-recording/1\n\nt_s,a_m,a_m\n",
       {},
       {"twice.csv:3: ", "column 'a_m' appears twice"}},
      {"short",
       head + "0,1,2\n0.001,1\n",
       {},
       {"short.csv:4: ", "has 2 fields, header has 3", "column 3 (temp_c) is missing"}},
      {"long",
       head + "0,1,2,3\n",
       {},
       {"long.csv:3: ", "more fields than the header's 3", "column 4 has no name in the header"}},
  };
  for (const auto& c : cases) {
    const std::string e = error_of(write_file(std::string(c.name) + ".csv", c.text), c.required);
    for (const auto& want : c.expected)
      EXPECT_NE(e.find(want), std::string::npos) << c.name << ": " << e;
  }
  EXPECT_NE(error_of(write_file("empty.csv", "# format: mls-recording/1\n\n"))
                .find("empty.csv: no header row"),
            std::string::npos);
  // An empty file says what a header looks like and where the format is described.
  const std::string empty = error_of(write_file("empty2.csv", ""));
  EXPECT_NE(empty.find("e.g. t_s,screw_angle_rad,nut_pos_m,load_force_n"), std::string::npos)
      << empty;
  EXPECT_NE(empty.find("docs/recording-format.md"), std::string::npos) << empty;
}

// A bad field far into a large file: the line count survives the block boundaries, comment and
// blank lines and CRLF endings.
TEST(Recording, ErrorLineIsExactDeepInALargeFile) {
  for (const std::string eol : {"\n", "\r\n"}) {
    std::string text =
        "# format: mls-recording/1" + eol + "# source: test" + eol + "t_s,x_m,y_n" + eol;
    std::size_t line = 3;
    for (int r = 0; r < 150000; ++r) {
      if (r % 1000 == 999) text += "# comment" + eol, ++line;
      if (r % 777 == 0) text += eol, ++line;
      text +=
          std::to_string(r) + ".125," + std::to_string(r % 97) + ",-1.0000000000000002e-05" + eol;
      ++line;
    }
    text += "150000,7,12.5e" + eol;
    ++line;
    text += "150001,7,12.5" + eol;
    const std::string e =
        error_of(write_file(eol.size() == 1 ? "deep_lf.csv" : "deep_crlf.csv", text));
    const std::string at =
        (eol.size() == 1 ? "deep_lf.csv:" : "deep_crlf.csv:") + std::to_string(line) + ": ";
    EXPECT_NE(e.find(at), std::string::npos) << e << " (want " << at << ")";
    EXPECT_NE(e.find("column 3 (y_n): '12.5e' is not a number"), std::string::npos) << e;
  }
}

TEST(Recording, CrLfLineEndings) {
  const auto p =
      write_file("crlf.csv",
                 "# format: mls-recording/1\r\n# source: bench 3\r\n\r\nt_s,x_m,temp_c\r\n"
                 "0,1.5,20\r\n0.001,,21\r\n0.002,2.5,\r\n");
  const Recording r = read_recording(p, {"t_s", "temp_c"});
  EXPECT_EQ(r.meta("source"), "bench 3");
  EXPECT_EQ(r.names, (std::vector<std::string>{"t_s", "x_m", "temp_c"}));
  ASSERT_EQ(r.rows(), 3u);
  EXPECT_EQ(r.column("t_s")[2], 0.002);
  EXPECT_TRUE(std::isnan(r.column("x_m")[1]));
  EXPECT_EQ(r.column("x_m")[2], 2.5);
  EXPECT_EQ(r.column("temp_c")[1], 21.0);
  EXPECT_TRUE(std::isnan(r.column("temp_c")[2]));

  const std::string e = error_of(write_file("crlf_bad.csv", "t_s,x_m\r\n0,1\r\n1,2x\r\n"));
  EXPECT_NE(e.find("crlf_bad.csv:3: column 2 (x_m): '2x' is not a number"), std::string::npos) << e;
}

// Excel's "CSV UTF-8" starts the file with a byte-order mark: read as if it were not there, and
// on a header line as much as on a metadata line.
TEST(Recording, AUtf8ByteOrderMarkIsSkipped) {
  for (const std::string first : {"# format: mls-recording/1\n", ""}) {
    const auto p =
        write_file("bom.csv", "\xEF\xBB\xBF" + first + "t_s,x_m\r\n0,1.5\r\n0.001,2.5\r\n");
    const Recording r = read_recording(p, {"t_s", "x_m"});
    EXPECT_EQ(r.names, (std::vector<std::string>{"t_s", "x_m"})) << first;
    ASSERT_EQ(r.rows(), 2u);
    EXPECT_EQ(r.column("x_m")[1], 2.5);
  }
}

TEST(Recording, TrailingLineWithoutNewline) {
  Recording r = read_recording(write_file("nonl.csv", "t_s,a_m\n0,1\n1,2"));
  ASSERT_EQ(r.rows(), 2u);
  EXPECT_EQ(r.column("a_m")[1], 2.0);

  r = read_recording(write_file("nonl_empty.csv", "t_s,a_m\n0,1\n1,"));
  ASSERT_EQ(r.rows(), 2u);
  EXPECT_TRUE(std::isnan(r.column("a_m")[1]));

  r = read_recording(write_file("nonl_cr.csv", "t_s,a_m\r\n0,1\r\n1,3\r"));
  ASSERT_EQ(r.rows(), 2u);
  EXPECT_EQ(r.column("a_m")[1], 3.0);

  r = read_recording(write_file("header_only.csv", "# format: mls-recording/1\nt_s,a_m"));
  EXPECT_EQ(r.names, (std::vector<std::string>{"t_s", "a_m"}));
  EXPECT_EQ(r.rows(), 0u);

  // A last line without a line end that is not a row: torn by a crash, dropped with a warning
  // naming the line; the rows before it are all there.
  r = read_recording(write_file("nonl_bad.csv", "t_s,a_m\n0,1\n1,z"));
  ASSERT_EQ(r.rows(), 1u);
  ASSERT_EQ(r.warnings.size(), 1u);
  EXPECT_NE(r.warnings[0].find("nonl_bad.csv:3: the last line has no line end and was dropped"),
            std::string::npos)
      << r.warnings[0];
  EXPECT_NE(r.warnings[0].find("'z' is not a number"), std::string::npos) << r.warnings[0];
}

// Issue 25: in an mls-recording/1 file every row ends with a line end, so a last line without
// one is torn even when it reads as numbers (a power cut can cut a row inside a number); a torn
// line anywhere before the last stays an error.
TEST(Recording, TornLastLineIsDroppedTornMiddleLineIsAnError) {
  const std::string head = "# format: mls-recording/1\nt_s,a_m,b_n\n";
  Recording r = read_recording(write_file("torn.csv", head + "0,1,2\n0.001,1,2\n0.002,1.2"));
  EXPECT_EQ(r.rows(), 2u);
  ASSERT_EQ(r.warnings.size(), 1u);
  EXPECT_NE(r.warnings[0].find("torn.csv:5: the last line has no line end and was dropped"),
            std::string::npos)
      << r.warnings[0];

  r = read_recording(write_file("whole.csv", head + "0,1,2\n0.001,1,2\n"));
  EXPECT_EQ(r.rows(), 2u);
  EXPECT_TRUE(r.warnings.empty());

  const std::string e = error_of(write_file("torn_mid.csv", head + "0,1,2\n0.001,1\n0.002,1,2\n"));
  EXPECT_NE(e.find("torn_mid.csv:4: has 2 fields, header has 3"), std::string::npos) << e;
}

// Binary or non-UTF-8 input is refused with the byte's value and place, never the bytes.
TEST(Recording, BinaryInputIsRefusedWithoutEchoingIt) {
  std::mt19937 rng(25);
  std::string noise(4096, '\0');
  for (auto& ch : noise) ch = static_cast<char>(rng() & 0xFF);
  const std::string latin1 =
      "# format: mls-recording/1\n# source: Pr\xFC"
      "fstand\nt_s\n0\n";
  const std::string in_row = "# format: mls-recording/1\nt_s,a_m\n0,1\n0.001,\x01\x02\x7F\n";
  for (const auto& [name, text, at] :
       {std::tuple{"noise.bin", noise, "noise.bin:1: byte 0x"},
        std::tuple{"latin1.csv", latin1, "latin1.csv:2: byte 0xFC at column 13 is not UTF-8"},
        std::tuple{"ctrl.csv", in_row, "ctrl.csv:4: byte 0x01 at column 7 is not UTF-8"}}) {
    const std::string e = error_of(write_file(name, text));
    EXPECT_NE(e.find(at), std::string::npos) << e;
    EXPECT_NE(e.find("the line is not shown"), std::string::npos) << e;
    for (const char ch : e)
      ASSERT_TRUE(ch >= 0x20 && ch < 0x7F) << name << ": the message echoes a non-ASCII byte";
  }
  // UTF-8 text is text.
  const Recording ok = read_recording(
      write_file("utf8.csv", "# format: mls-recording/1\n# source: Prüfstand µ ✓\nt_s\n0\n"));
  EXPECT_EQ(ok.meta("source"), "Prüfstand µ ✓");
}

// Values that cannot be in the column's unit are refused naming the column, the values and the
// likely unit; values at the scale of any plausible machine pass.
TEST(Recording, ColumnsThatCannotBeInTheirUnitAreRefused) {
  const std::string head =
      "# format: mls-recording/1\n# sample_rate_hz: 1000\nt_s,screw_angle_rad,nut_pos_m\n";
  struct Case {
    const char* name;
    std::string rows;
    std::vector<std::string> expected;
  };
  const std::vector<Case> cases = {
      {"pos_mm",
       "0,20.85,20.0003\n0.001,20.86,20.0105\n",
       {"pos_mm.csv: column nut_pos_m cannot be in metres", "20.0003 at data row 1",
        "beyond +-10 m", "likely unit: millimetres"}},
      {"angle_urad",
       "0,20854236,0.02\n0.001,20864236,0.02\n0.002,20954236,0.02\n",
       {"column screw_angle_rad cannot be in radians", "jumps by 90000 rad",
        "from 2.08642e+07 to 2.09542e+07 at data row 3", "likely unit: microradians"}},
      {"time_ms",
       "0,20.85,0.02\n1,20.86,0.02\n2,20.87,0.02\n3,20.88,0.02\n",
       {"column t_s cannot be in seconds", "advances by 1 per row", "sample_rate_hz 1000",
        "likely unit: milliseconds"}},
  };
  for (const auto& c : cases) {
    const std::string e = error_of(write_file(std::string(c.name) + ".csv", head + c.rows));
    for (const auto& want : c.expected)
      EXPECT_NE(e.find(want), std::string::npos) << c.name << ": " << e;
  }
  // Plausible: a long stroke, fast turning (10 turns a sample), time at the header's rate.
  const Recording r = read_recording(
      write_file("plausible.csv", head + "0,0,-2.5\n0.001,62.8,9.9\n0.002,125.6,0\n"));
  EXPECT_EQ(r.rows(), 3u);
  // The bound can come from the caller's configuration, and its source is quoted.
  PlausibleRanges stroke;
  stroke.position_bound_m = 0.5;
  stroke.position_bound_source = "10 x the configured stroke";
  try {
    check_plausible_units(r, stroke);
    ADD_FAILURE() << "9.9 m passed a 0.5 m bound";
  } catch (const RecordingError& e) {
    EXPECT_NE(std::string(e.what()).find("beyond +-0.5 m (10 x the configured stroke)"),
              std::string::npos)
        << e.what();
  }
}

// A streaming writer puts each row in the file as it is given (a SIGKILL loses none of them); a
// whole writer shows nothing under the name until close(), and leaves the old file when it is
// never closed.
TEST(RecordingWriter, StreamingRowsAreInTheFileAtOnceWholeFilesAppearAtClose) {
  const std::string dir = test_tmp_dir();
  const std::string streamed = dir + "/streamed.csv";
  RecordingWriter s(streamed, {{"sample_rate_hz", "1000"}}, {"t_s", "nut_pos_m"});
  const double rows[3][2] = {{0.0, 0.026}, {0.001, 0.020011}, {0.002, NAN}};
  for (const auto& row : rows) s.write_row(row, 2);
  std::ifstream in(streamed);
  const std::string text{std::istreambuf_iterator<char>(in), {}};
  EXPECT_EQ(text,
            "# format: mls-recording/1\n# sample_rate_hz: 1000\nt_s,nut_pos_m\n0,0.026\n"
            "0.001,0.020011\n0.002,\n");
  s.close();

  const std::string whole = dir + "/whole.csv";
  write_file("whole.csv", "old\n");
  {
    RecordingWriter w(whole, {}, {"t_s"}, WriteMode::whole);
    const double t = 0.5;
    w.write_row(&t, 1);
    std::ifstream old(whole);
    EXPECT_EQ(std::string(std::istreambuf_iterator<char>(old), {}), "old\n");
  }  // never closed: the old file stays, the temporary file is gone
  std::ifstream still(whole);
  EXPECT_EQ(std::string(std::istreambuf_iterator<char>(still), {}), "old\n");
  {
    RecordingWriter w(whole, {}, {"t_s"}, WriteMode::whole);
    const double t = 0.5;
    w.write_row(&t, 1);
    w.close();
  }
  EXPECT_EQ(read_recording(whole).column("t_s"), std::vector<double>{0.5});
  std::size_t files = 0;
  for ([[maybe_unused]] const auto& f : std::filesystem::directory_iterator(dir)) ++files;
  EXPECT_EQ(files, 2u) << "a temporary file was left behind";
}

// Rows need not be tidy: spaces around fields, a '+' sign, comment and blank lines between rows.
TEST(Recording, UntidyRowsAreRead) {
  const Recording r = read_recording(
      write_file("untidy.csv", "t_s, a_m ,b_n\n 0 , +1.5,2\n\n# pause\n0.5,-0, \n1,1e-3,+7\n"));
  EXPECT_EQ(r.names, (std::vector<std::string>{"t_s", "a_m", "b_n"}));
  ASSERT_EQ(r.rows(), 3u);
  EXPECT_EQ(r.column("a_m")[0], 1.5);
  EXPECT_EQ(bits(r.column("a_m")[1]), bits(-0.0));
  EXPECT_TRUE(std::isnan(r.column("b_n")[1]));
  EXPECT_EQ(r.column("b_n")[2], 7.0);
  EXPECT_EQ(r.column("t_s")[2], 1.0);
}

// A line longer than the reader's block (1 MiB) is read whole.
TEST(Recording, LinesLongerThanTheReadBlock) {
  const std::string note(3 << 20, 'n');
  const Recording r =
      read_recording(write_file("longline.csv", "# note: " + note + "\nt_s\n0\n1\n"));
  EXPECT_EQ(r.meta("note"), note);
  ASSERT_EQ(r.rows(), 2u);
  EXPECT_EQ(r.column("t_s")[1], 1.0);
}

// The one error-statistics helper: exact values on a small hand-checked signal.
TEST(ErrorStats, MeanAbsRmsMaxAndPercentileSkipGaps) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const std::vector<double> e{3.0, -4.0, nan, 0.0};
  const maglead::ErrorStats s = maglead::error_stats(e);
  EXPECT_EQ(s.samples, 3u);
  EXPECT_DOUBLE_EQ(s.mean_abs, 7.0 / 3.0);
  EXPECT_DOUBLE_EQ(s.rms, std::sqrt(25.0 / 3.0));
  EXPECT_DOUBLE_EQ(s.max_abs, 4.0);
  const std::vector<double> est{1.0, 2.0}, ref{1.5, 2.0, 9.0};
  EXPECT_DOUBLE_EQ(maglead::error_stats(est, ref).max_abs, 0.5);
  EXPECT_TRUE(std::isnan(maglead::error_stats(std::vector<double>{nan}).rms));
  EXPECT_DOUBLE_EQ(maglead::percentile({5, 1, nan, 4, 2, 3}, 0.5), 3.0);
  EXPECT_DOUBLE_EQ(maglead::percentile({5, 1, 4, 2, 3}, 1.0), 5.0);
  EXPECT_TRUE(std::isnan(maglead::percentile({}, 0.5)));
}

// Rows one sample period apart are what every reader assumes (issue 43: the analysis took a
// recorder's missed cycles, repeated rows and a wrong header rate as evenly spaced).
namespace {
/// A 1 kHz recording of x = 2·t over `n` rows, without the rows `drop` says to leave out and
/// with those `twice` says written twice, under a header line of `rate_hz` (0: none).
std::string sampled(int n, const std::function<bool(int)>& drop, double rate_hz = 1000.0,
                    const std::function<bool(int)>& twice = {}) {
  std::string s = "# format: mls-recording/1\n";
  if (rate_hz > 0) s += "# sample_rate_hz: " + std::to_string(rate_hz) + "\n";
  s += "t_s,x_m,status_word\n";
  char row[96];
  for (int i = 0; i < n; ++i) {
    if (drop(i)) continue;
    std::snprintf(row, sizeof row, "%.3f,%.6f,%d\n", i * 1e-3, 2e-3 * i, i < n / 2 ? 3 : 7);
    s += row;
    if (twice && twice(i)) s += row;
  }
  return s;
}
bool none(int) { return false; }
}  // namespace

// A recorder killed a few polls in, one of them missed: a sixth of a short file is missing, but
// one filled gap's worth, not a wrong rate (record_sigkill met it under a loaded CI machine).
TEST(Recording, AShortRecordingMissingOnePollIsFilled) {
  const auto p = write_file("short_gap.csv", sampled(6, [](int i) { return i == 3; }));
  const Recording r = read_recording(p);
  EXPECT_EQ(r.rows(), 6u);
  EXPECT_NEAR(r.column("t_s")[3], 0.003, 1e-12);
}

TEST(Recording, MissedRowsAreFilledOntoTheSamplePeriod) {
  // Rows 100, 101 and 500 missing (a recorder that fell two cycles, then one, behind), and 30
  // from row 600 (a stall of 30 ms, within the 50 ms filled).
  const auto p = write_file("gaps.csv", sampled(1000, [](int i) {
                              return i == 100 || i == 101 || i == 500 || (i >= 600 && i < 630);
                            }));
  const Recording r = read_recording(p);
  ASSERT_EQ(r.rows(), 1000u);
  const auto& t = r.column("t_s");
  const auto& x = r.column("x_m");
  for (std::size_t i = 0; i < t.size(); ++i) {
    EXPECT_NEAR(t[i], static_cast<double>(i) * 1e-3, 1e-9) << i;
    EXPECT_NEAR(x[i], 2e-3 * static_cast<double>(i), 1e-9) << i;
  }
  EXPECT_EQ(r.column("status_word")[500], 3.0);  // a code keeps the value before (not 5, half-way)
  ASSERT_EQ(r.warnings.size(), 1u);
  EXPECT_NE(r.warnings[0].find("filled 33 missing rows in 3 gaps of t_s (the longest 30 rows"),
            std::string::npos)
      << r.warnings[0];
  // Evenly sampled files pass untouched and silent.
  EXPECT_TRUE(read_recording(write_file("even.csv", sampled(1000, none))).warnings.empty());
}

TEST(Recording, RowsTheHeaderRateContradictsAreRefused) {
  const std::string low = error_of(write_file("rate_low.csv", sampled(1000, none, 100.0)));
  EXPECT_NE(low.find("more than 100 Hz allows"), std::string::npos) << low;
  EXPECT_NE(low.find("1000 Hz"), std::string::npos) << low;  // what the rows say
  const std::string thin =
      error_of(write_file("rate_high.csv", sampled(1000, [](int i) { return i % 10 != 0; })));
  EXPECT_NE(thin.find("are missing"), std::string::npos) << thin;
  EXPECT_NE(thin.find("100 Hz"), std::string::npos) << thin;
  const std::string twice = error_of(
      write_file("repeated.csv", sampled(1000, none, 0, [](int i) { return i % 10 == 0; })));
  EXPECT_NE(twice.find("100 rows repeat the time of the row before, at data rows 2 (t = 0 s), "
                       "13 (t = 0.01 s), 24 (t = 0.02 s), 35 (t = 0.03 s), 46 (t = 0.04 s), …"),
            std::string::npos)
      << twice;
  EXPECT_NE(twice.find("copies, delete them"), std::string::npos) << twice;
  const std::string all_twice =
      error_of(write_file("all_twice.csv", sampled(1000, none, 0, [](int) { return true; })));
  EXPECT_NE(all_twice.find("repeat"), std::string::npos) << all_twice;
  const std::string hole =
      error_of(write_file("hole.csv", sampled(1000, [](int i) { return i > 300 && i < 400; })));
  EXPECT_NE(hole.find("99 rows missing"), std::string::npos) << hole;
  EXPECT_NE(hole.find("as two recordings"), std::string::npos) << hole;
  // A rate that is no number: every reader refuses it alike (none guesses from the stamps).
  std::string fast = sampled(1000, none, 0);
  fast.insert(fast.find('\n') + 1, "# sample_rate_hz: fast\n");
  EXPECT_EQ(error_of(write_file("rate_word.csv", fast)),
            test_tmp_dir() +
                "/rate_word.csv: header sample_rate_hz 'fast' is not a positive "
                "number: fix the '# sample_rate_hz:' line or delete it");
}

// One row written twice in 1000 is within the rate's 1 % and 3 rows, yet shifts every later row
// by a period (the walkthrough's b_dup.csv: held-out gain 99.8 % fell to 44 %); a time stamp
// written twice with another row's values left a 2 ms step that filling turned into an extra row.
TEST(Recording, ARepeatedTimeStampIsRefusedWithItsRow) {
  const std::string copy = error_of(
      write_file("one_copy.csv", sampled(1000, none, 1000.0, [](int i) { return i == 500; })));
  EXPECT_NE(copy.find("1 row repeats the time of the row before, at data row 502 (t = 0.5 s)"),
            std::string::npos)
      << copy;
  EXPECT_NE(copy.find("the repeated rows are copies, delete them"), std::string::npos) << copy;
  std::string stamp = sampled(1000, none);
  const auto at = stamp.find("\n0.501,");
  ASSERT_NE(at, std::string::npos);
  stamp.replace(at + 1, 5, "0.500");  // row 501 stamped as row 500
  const std::string wrong = error_of(write_file("stamp_twice.csv", stamp));
  EXPECT_NE(wrong.find("at data row 502 (t = 0.5 s)"), std::string::npos) << wrong;
  EXPECT_NE(wrong.find("the time stamps are wrong: fix t_s"), std::string::npos) << wrong;
  // A recorder's jitter (steps of 0.6 and 1.4 periods, never 0) is still read, as are the rows
  // `record` writes (its cycle counter never writes one cycle twice).
  std::string jitter = "# format: mls-recording/1\n# sample_rate_hz: 1000\nt_s,x_m\n";
  for (int i = 0; i < 1000; ++i)
    jitter +=
        std::to_string(1e-3 * i + (i % 2 == 0 ? 2e-4 : -2e-4)) + "," + std::to_string(i) + "\n";
  EXPECT_EQ(read_recording(write_file("jitter.csv", jitter)).rows(), 1000u);
  // Written with three decimals at 2 kHz: every other stamp repeats, and that is what is said.
  std::string coarse = "# format: mls-recording/1\nt_s,x_m\n";
  for (int i = 0; i < 1000; ++i) {
    char row[48];
    std::snprintf(row, sizeof row, "%.3f,%d\n", 5e-4 * i, i);
    coarse += row;
  }
  const std::string few = error_of(write_file("coarse.csv", coarse));
  EXPECT_NE(few.find("t_s has too few decimals for its rate"), std::string::npos) << few;
}
