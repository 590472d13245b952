#!/usr/bin/env bash
# Set up a fresh Debian 12 machine for fiberfem: install every Debian package the
# project needs, configure and build. Idempotent: a second call skips what is done.
#
#   scripts/setup.sh            install + configure + build (release preset, build/)
#   FIBERFEM_SKIP_APT=1 ...     skip the package step (packages managed elsewhere)
#   FIBERFEM_BUILD_TARGETS=fiberfem ...  build only these targets
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$here"

packages=(
  build-essential cmake ninja-build pkg-config git
  libeigen3-dev libsuitesparse-dev libopenblas0-pthread
  libgtest-dev libgmock-dev libbenchmark-dev
  libyaml-cpp-dev libcli11-dev libspdlog-dev libfmt-dev libpng-dev libssl-dev nlohmann-json3-dev
  cyclonedds-dev cyclonedds-tools libhdf5-dev hdf5-tools
  # pvpython: the archive's XDMF sidecar is tested in ParaView's own reader
  python3-paraview
  libosmesa6-dev ffmpeg libfreetype-dev fonts-dejavu-core
  python3 python3-venv time
  # the gmsh wheel's runtime libraries (scripts/make_*.py regenerate the shipped meshes)
  libglu1-mesa libxcursor1 libxft2 libxinerama1 libgl1 libfontconfig1
  # secure mode (docs/security.md): scripts/make_security.sh makes the CAs and identities
  openssl
  # ip netns: the several-hosts test (tests/service/netns_test.cpp)
  iproute2
  # the fuzz-labelled test: clang, libFuzzer and the sanitizers (scripts/fuzz.sh)
  clang libclang-rt-14-dev libomp-14-dev ccache
  # the amg preconditioner (AMGCL, header-only; Debian's contrib component, enabled below)
  libamgcl-dev
  # Boost.Graph's reverse Cuthill-McKee numbering of the engine's DOFs (header-only)
  libboost-dev
  # fiberfem web (docs/web.md): headless Chromium and its WebDriver for the browser tests;
  # Python's headers for the bridge's cyclonedds binding, built against the system library
  chromium chromium-driver python3-dev
)
# node and npm bundle the page of fiberfem web (clients/web) at build time; a machine that
# has them from elsewhere keeps its own (Debian's npm conflicts with other nodejs builds).
if ! command -v node >/dev/null || ! command -v npm >/dev/null; then
  packages+=(nodejs npm)
fi

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [[ "${FIBERFEM_SKIP_APT:-0}" != 1 && ${#missing[@]} -gt 0 ]]; then
  echo "setup: installing ${#missing[@]} Debian packages: ${missing[*]}"
  sudo_cmd=()
  if [[ $(id -u) -ne 0 ]]; then sudo_cmd=(sudo); fi
  export DEBIAN_FRONTEND=noninteractive
  "${sudo_cmd[@]}" apt-get update -q
  # libamgcl-dev is in Debian's contrib component, not main: add contrib for the same
  # archive when no configured source offers the package yet.
  # The mirror is the one the machine already uses for its release (first deb822 stanza or
  # sources.list line naming the release), else Debian's default.
  if [[ " ${missing[*]} " == *" libamgcl-dev "* ]] && ! apt-cache policy libamgcl-dev | grep -q "Candidate: [0-9]"; then
    codename="$(. /etc/os-release && echo "$VERSION_CODENAME")"
    mirror=""
    for f in /etc/apt/sources.list.d/*.sources; do
      [[ -r "$f" && -z "$mirror" ]] || continue
      uris="" suites=""
      while IFS= read -r line || [[ -n "$line" ]]; do
        case "$line" in
          URIs:*) uris="${line#URIs:}" ;;
          Suites:*) suites="${line#Suites:}" ;;
          "") [[ " $suites " == *" $codename "* && -n "$uris" ]] && { mirror="$(echo $uris | cut -d' ' -f1)"; break; }
              uris="" suites="" ;;
        esac
      done <"$f"
      [[ -z "$mirror" && " $suites " == *" $codename "* && -n "$uris" ]] && mirror="$(echo $uris | cut -d' ' -f1)"
    done
    if [[ -z "$mirror" && -r /etc/apt/sources.list ]]; then
      mirror="$(awk -v c="$codename" '$1 == "deb" { for (i = 2; i < NF; i++) if ($i ~ /^[a-z+]+:\/\// && $(i + 1) == c) { print $i; exit } }' /etc/apt/sources.list)"
    fi
    mirror="${mirror:-http://deb.debian.org/debian}"
    echo "setup: enabling Debian's contrib component for libamgcl-dev (from $mirror)"
    printf 'Types: deb\nURIs: %s\nSuites: %s %s-updates\nComponents: contrib\nSigned-By: /usr/share/keyrings/debian-archive-keyring.gpg\n' \
      "$mirror" "$codename" "$codename" |
      "${sudo_cmd[@]}" tee /etc/apt/sources.list.d/fiberfem-contrib.sources >/dev/null
    "${sudo_cmd[@]}" apt-get update -q
  fi
  "${sudo_cmd[@]}" apt-get install -y -q --no-install-recommends "${missing[@]}"
else
  echo "setup: Debian packages already installed"
fi

# Python packages (tests and tools) in a virtual environment beside the build.
if ! .venv/bin/python -c "import meshio, gmsh, h5py, cyclonedds, fiberfem_client, dask, distributed, pandas, pyarrow, scipy, yaml, tqdm, fiberfem_client.sweep, aiohttp, selenium, circulation.regazzoni2020" 2>/dev/null; then
  echo "setup: creating .venv with scripts/requirements.txt and the Python client (clients/python)"
  python3 -m venv .venv
  .venv/bin/pip install -q -r scripts/requirements.txt
  .venv/bin/pip install -q -e clients/python
else
  echo "setup: .venv ready"
fi

# .venv-web: the bridge of fiberfem web on the system's Cyclone DDS (docs/web.md): the
# cyclonedds binding built from its source against cyclonedds-dev (a CYCLONEDDS_HOME of links
# to the Debian files), so the bridge speaks DDS Security like the service.
if ! .venv-web/bin/python -c "import cyclonedds, aiohttp, fiberfem_client.web" 2>/dev/null; then
  echo "setup: creating .venv-web with scripts/requirements-web.txt (cyclonedds built against the system library)"
  cdds_home="$(mktemp -d)"
  mkdir -p "$cdds_home/lib" "$cdds_home/bin"
  ln -s /usr/include "$cdds_home/include"
  ln -s "$(dpkg -L cyclonedds-dev | grep '/libddsc\.so$' | head -n 1)" "$cdds_home/lib/libddsc.so"
  ln -s "$(command -v idlc)" "$cdds_home/bin/idlc"
  python3 -m venv .venv-web
  CYCLONEDDS_HOME="$cdds_home" .venv-web/bin/pip install -q --no-binary cyclonedds -r scripts/requirements-web.txt
  .venv-web/bin/pip install -q --no-deps -e clients/python
  rm -rf "$cdds_home"
else
  echo "setup: .venv-web ready"
fi

# three.js and esbuild (clients/web/package-lock.json) for the page of fiberfem web.
if [[ ! -x clients/web/node_modules/.bin/esbuild || clients/web/package-lock.json -nt clients/web/node_modules ]]; then
  echo "setup: npm ci in clients/web (three.js, esbuild)"
  (cd clients/web && npm ci --no-audit --no-fund --loglevel=error && touch node_modules)
fi

preset="${FIBERFEM_PRESET:-release}"
if [[ ! -f "build/$preset/build.ninja" ]]; then
  cmake --preset "$preset"
elif [[ "$preset" != core-only ]] && ! grep -q fiberfem_web_page "build/$preset/build.ninja"; then
  cmake --preset "$preset"  # configured before node_modules existed: add the page's target
fi
# FIBERFEM_BUILD_TARGETS="fiberfem ..." builds only those (the front door needs just the
# command; the test command builds the rest).
if [[ -n "${FIBERFEM_BUILD_TARGETS:-}" ]]; then
  # shellcheck disable=SC2086
  cmake --build --preset "$preset" --target ${FIBERFEM_BUILD_TARGETS}
else
  cmake --build --preset "$preset"
fi
echo "setup: build ready in build/$preset"
