#include <iomanip>
#include <sstream>

#include "maglead/fileio/atomic_file.hpp"
#include "maglead/physics/toml_config.hpp"
#include "maglead/settings/settings.hpp"

namespace maglead {

namespace {

std::string join(const std::vector<double>& v) {
  std::ostringstream s;
  s << std::setprecision(10) << "[";
  for (std::size_t i = 0; i < v.size(); ++i) s << (i ? ", " : "") << v[i];
  s << "]";
  return s.str();
}

}  // namespace

void save_calibration(const std::string& path, const ForceCalibration& cal,
                      const std::string& header_comment) {
  std::ostringstream out;  // then written atomically: a crash never leaves half a calibration
  out << "# maglead force calibration: load-cell force on the nut [N] against phase phi [rad]\n";
  if (!header_comment.empty()) out << "# " << header_comment << "\n";
  out << std::setprecision(10) << "[calibration]\n"
      << "source = \"" << cal.source << "\"\n"
      << "# F_s(phi) = sum c_k phi^k, valid on the stable branch\n"
      << "polynomial_coeffs_ascending = " << join(cal.polynomial.coeffs_ascending) << "\n"
      << "# periodic model: mean + sum a_k cos(k phi) + b_k sin(k phi)\n"
      << "periodic_mean_n = " << cal.periodic.mean_n << "\n"
      << "periodic_cos_n = " << join(cal.periodic.cos_n) << "\n"
      << "periodic_sin_n = " << join(cal.periodic.sin_n) << "\n";
  write_file_atomically(path, out.str());
}

ForceCalibration load_calibration(const std::string& path) {
  const toml::table root = config::parse_file(path);
  const toml::table* t = config::section(path, root, "calibration", true);
  ForceCalibration cal;
  cal.source = (*t)["source"].value_or(std::string(path));
  cal.polynomial.coeffs_ascending =
      config::read_numbers(path, *t, "[calibration]", "polynomial_coeffs_ascending");
  if (cal.polynomial.coeffs_ascending.size() < 2)
    config::fail(path, t->get("polynomial_coeffs_ascending"),
                 "[calibration] polynomial needs order 1 or more");
  if (!config::read_number(path, *t, "[calibration]", "periodic_mean_n", cal.periodic.mean_n))
    config::fail(path, t, "[calibration] periodic_mean_n missing");
  cal.periodic.cos_n = config::read_numbers(path, *t, "[calibration]", "periodic_cos_n");
  cal.periodic.sin_n = config::read_numbers(path, *t, "[calibration]", "periodic_sin_n");
  if (cal.periodic.cos_n.size() != cal.periodic.sin_n.size())
    config::fail(path, t->get("periodic_sin_n"),
                 "[calibration] periodic_cos_n and periodic_sin_n differ in length");
  cal.derive_limits();
  if (!(cal.peak_push_n > 0.0) || !(cal.peak_pull_n < 0.0))
    config::fail(
        path, t->get("polynomial_coeffs_ascending"),
        "[calibration] curve has no stable branch around phi = 0 (force must fall with phase)");
  // Finite coefficients can still overflow at the branch's edge (a coefficient of 1e308).
  if (!std::isfinite(cal.peak_push_n) || !std::isfinite(cal.peak_pull_n))
    config::fail(path, t->get("polynomial_coeffs_ascending"),
                 "[calibration] curve's peak force on its stable branch is not a finite number");
  return cal;
}

}  // namespace maglead
