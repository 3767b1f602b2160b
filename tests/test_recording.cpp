// The mls-recording/1 reader: round trip, and errors that name the file, line and column.
#include <gtest/gtest.h>

#include "test_tmp.hpp"

#include <cmath>
#include <fstream>

#include "maglead/recording/recording.hpp"

using namespace maglead;

namespace {
std::string write_file(const std::string& name, const std::string& text) {
  const std::string path = test_tmp_dir() + "/" + name;
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

TEST(Recording, NonNumericFieldNamesLineAndColumn) {
  const auto p = write_file("nan.csv", "# format: mls-recording/1\nt_s,nut_pos_m\n0,0\n0.001,abc\n");
  const std::string e = error_of(p);
  EXPECT_NE(e.find("nan.csv:4"), std::string::npos) << e;
  EXPECT_NE(e.find("column 2 (nut_pos_m)"), std::string::npos) << e;
  EXPECT_NE(e.find("'abc'"), std::string::npos) << e;
}

TEST(Recording, DecreasingTimeIsAnError) {
  const auto p = write_file("back.csv", "t_s,x_m\n0,0\n0.002,0\n0.001,0\n");
  const std::string e = error_of(p);
  EXPECT_NE(e.find("back.csv:4"), std::string::npos) << e;
  EXPECT_NE(e.find("time decreases"), std::string::npos) << e;
}

TEST(Recording, RaggedRowsAndForeignFormatsAreErrors) {
  EXPECT_NE(error_of(write_file("short.csv", "t_s,a_m\n0\n")).find("short.csv:2"), std::string::npos);
  EXPECT_NE(error_of(write_file("long.csv", "t_s,a_m\n0,1,2\n")).find("more fields"), std::string::npos);
  EXPECT_NE(error_of(write_file("fmt.csv", "# format: other/2\nt_s\n0\n")).find("other/2"),
            std::string::npos);
  EXPECT_NE(error_of(test_tmp_dir() + "/does-not-exist.csv").find("cannot open"),
            std::string::npos);
}
