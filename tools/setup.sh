#!/usr/bin/env bash
# Installs maglead's build and test dependencies from Debian packages. Idempotent: when
# everything is present it only checks and returns.
set -euo pipefail
packages=(
  g++ cmake ninja-build pkg-config          # toolchain
  clang libclang-rt-14-dev                  # libFuzzer and its sanitizers (tools/fuzz.sh)
  libmodbus-dev                             # Modbus TCP/RTU framing, CRC, serial line
  libeigen3-dev                             # least squares for calibration and analysis
  libsundials-dev                           # CVODE: the twin's hybrid ODE integration
  libopencv-core-dev libopencv-imgproc-dev  # drawing plots and maps
  libpng-dev libjpeg62-turbo-dev            # encoding them as PNG and JPEG
  libcli11-dev                              # command-line parsing
  libtomlplusplus-dev                       # config files (TOML)
  nlohmann-json3-dev                        # JSON output
  googletest libgtest-dev                   # tests
  python3-pymodbus mbpoll socat             # independent Modbus clients for integration tests
  python3-serial python3-serial-asyncio     # pymodbus.client imports these even for TCP
  libjs-dygraphs                            # interactive time plots, inlined into the HTML report
  chromium                                  # headless browser: the anomaly report renders (tests)
  tmux                                      # a real terminal for the `maglead watch` test
  dpkg-dev file                             # cpack's .deb: dpkg-shlibdeps for the dependencies (test)
  python3-pandas                            # bench analyze: read_csv as the CSV reading reference
  python3-jsonschema                        # analysis.json, report.json against docs/schema (test)
  help2man                                  # the man page maglead(1) from the commands' --help
)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  echo "setup: installing ${missing[*]}"
  SUDO=""
  [ "$(id -u)" -eq 0 ] || SUDO="sudo"
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get update -qq
  $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi
echo "setup: all dependencies present"
