#!/usr/bin/env bash
# Build dist/edge-vis.pyz: edge-vis and every dependency in one executable file (a shiv
# zipapp), for the Python version and CPU architecture of the building machine.
#
#   bash deploy/build-bundle.sh            # or: make bundle
#
# Environment:
#   PYTHON               interpreter to build for (default .venv/bin/python, else python3);
#                        the relay needs the same major.minor version
#   EDGE_VIS_WHEELHOUSE  where wheels are kept between builds (default build/wheelhouse)
#   EDGE_VIS_BUNDLE      output file (default dist/edge-vis.pyz)
#
# What goes in: edge-vis with its links and translators, cyclonedds (its wheel carries the
# Cyclone C library), pyserial, and udt4py when the build machine has it (a compiled
# extension linked against the system libudt: the relay needs Debian's libudt0). The
# cyclonedds command-line tools' dependencies (rich-click, ...) are left out: the relay
# only uses the library. Wheels come from the build machine's cache or PyPI; udt4py is
# built from source against libudt-dev (see scripts/setup.sh) when no wheel is cached, and
# with it the lanes' congestion control (links/udt/udt_cc.cpp) beside its loader.
#
# DDS Security: with PYTHON=.venv-secure/bin/python (scripts/setup.sh --secure) the bundle
# carries that environment's cyclonedds binding, built again from source against Debian's
# Cyclone DDS (never the PyPI wheel of the same version, whose bundled library has no
# security plugins), kept apart in build/wheelhouse/secure. The relay then
# needs Debian's libddsc0debian installed, and the build fails if the assembled bundle
# would not have DDS Security.
set -euo pipefail

here=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cd "$here"
if [[ -z ${PYTHON:-} ]]; then
    if [[ -x .venv/bin/python ]]; then PYTHON=.venv/bin/python; else PYTHON=python3; fi
fi
# the build Python's binding loads a system Cyclone DDS (the secure set-up): its version
secure=$("$PYTHON" - <<'EOF' 2>/dev/null || true
from importlib.metadata import version
from cyclonedds import __library__ as library
if library.in_wheel is False:
    print(version("cyclonedds"))
EOF
)
wheelhouse=${EDGE_VIS_WHEELHOUSE:-$here/build/wheelhouse}
# the binding built against the system library, apart from the index's wheels
secure_wheels="$wheelhouse/secure"
out=${EDGE_VIS_BUNDLE:-$here/dist/edge-vis.pyz}
mkdir -p "$wheelhouse" "$(dirname "$out")"
work=$(mktemp -d "${TMPDIR:-/tmp}/edge-vis-bundle.XXXXXX")
trap 'rm -rf "$work"' EXIT

say() { printf 'build-bundle: %s\n' "$*" >&2; }
pip() { "$PYTHON" -m pip --disable-pip-version-check "$@"; }

# Pin what the build environment runs (what was tested), else the project's ranges.
pin() {  # pin DIST FALLBACK_SPEC
    local v
    v=$("$PYTHON" -c "import importlib.metadata as m, sys
try: print(m.version(sys.argv[1]))
except m.PackageNotFoundError: pass" "$1")
    if [[ -n $v ]]; then echo "$1==$v"; else echo "$2"; fi
}

# 1. edge-vis itself, from the working tree as it is. The default profile goes inside the
#    package so `edge-vis check` / `run` without --profile work from the bundle too.
say "building the edge-vis wheel with $("$PYTHON" -c 'import sys; print(sys.version.split()[0])')"
mkdir -p "$work/src"
cp -r pyproject.toml README.md edge_vis links translators "$work/src/"
find "$work/src" -name __pycache__ -prune -exec rm -rf {} +
mkdir -p "$work/src/edge_vis/data"
[[ -f "$work/src/edge_vis/data/default.toml" ]] || cp profiles/default.toml "$work/src/edge_vis/data/"
rm -f "$wheelhouse"/edge_vis-*.whl
pip wheel -q --no-deps -w "$wheelhouse" "$work/src"

# 2. dependencies, reusing wheels already in the wheelhouse
deps=("$(pin cyclonedds 'cyclonedds>=0.10')" "$(pin pyserial 'pyserial>=3.5')")
if [[ -n $secure ]] && ! compgen -G "$secure_wheels/cyclonedds-$secure-*.whl" >/dev/null; then
    # as scripts/setup.sh --secure builds it: $CYCLONEDDS_HOME/{include,bin,lib} are
    # Debian's /usr/include, /usr/bin and multiarch library folder
    multiarch="$(dpkg-architecture -qDEB_HOST_MULTIARCH 2>/dev/null || gcc -print-multiarch)"
    home="$work/cyclonedds-home"
    mkdir -p "$home"
    ln -s /usr/include "$home/include"
    ln -s /usr/bin "$home/bin"
    ln -s "/usr/lib/$multiarch" "$home/lib"
    say "building cyclonedds==$secure against Debian's Cyclone DDS (DDS Security)"
    rm -rf "$secure_wheels"
    CYCLONEDDS_HOME="$home" pip wheel -q --no-deps --no-cache-dir --no-binary cyclonedds \
        -w "$secure_wheels" "cyclonedds==$secure"
fi
if [[ -n $secure ]]; then
    fetch=("${deps[@]:1}")  # the index's wheel of that version must not replace it
else
    fetch=("${deps[@]}")
fi
say "fetching ${fetch[*]}"
pip wheel -q --no-deps --find-links "$wheelhouse" -w "$wheelhouse" "${fetch[@]}"
if "$PYTHON" -c "import udt4py" 2>/dev/null; then
    udt=$(pin udt4py 'udt4py>=1.2')
    say "building $udt (needs Cython and wheel in the build environment, and libudt-dev)"
    pip wheel -q --no-deps --no-build-isolation --find-links "$wheelhouse" -w "$wheelhouse" "$udt"
    deps+=("$udt")
else
    say "udt4py is not installed for $PYTHON: the bundle has no udt:// link"
fi

# 3. one site-packages with exactly these distributions, then the zipapp
say "assembling $out"
if [[ -n $secure ]]; then  # that very wheel, whatever else the wheelhouse holds
    deps[0]=$(echo "$secure_wheels"/cyclonedds-*.whl)
fi
pip install -q --no-deps --no-index --find-links "$wheelhouse" --target "$work/site" \
    edge-vis "${deps[@]}"
rm -rf "$work/site/bin"
# the lanes' congestion control (links/udt/udt_cc.cpp), beside the module that loads it;
# without it the relay's lanes keep libudt's own control (slower on lossy radios)
if [[ -d "$work/site/udt4py" ]] || compgen -G "$work/site/udt4py*.so" >/dev/null; then
    cxx=$(command -v c++ || command -v g++ || true)
    if [[ -n $cxx ]] && "$cxx" -std=c++17 -O2 -shared -fPIC \
            -o "$work/site/links/udt/libedge_udt_cc.so" links/udt/udt_cc.cpp -ludt; then
        say "built the lanes' congestion control into the bundle"
    else
        say "no C++ compiler or libudt-dev: the bundle's lanes keep libudt's own congestion control"
    fi
fi
if [[ -n $secure ]] && ! "$PYTHON" -S - "$work/site" <<'EOF'
import sys
sys.path.insert(0, sys.argv[1])
import cyclonedds.core  # noqa: F401  loads the library the bundle will load
from edge_vis.dds.secure_qos import security_available
sys.exit(not security_available())
EOF
then
    echo "build-bundle: the assembled cyclonedds does not load Debian's Cyclone DDS:" \
         "the bundle would have no DDS Security" >&2
    exit 1
fi
# Byte-code that stays valid after extraction (file times change then): the first start on
# the relay does not compile anything.
"$PYTHON" -m compileall -q -f --invalidation-mode unchecked-hash "$work/site" >/dev/null
if ! "$PYTHON" -c "import shiv" 2>/dev/null; then
    pip install -q --target "$work/tools" 'shiv>=1.0.4,<2'
    export PYTHONPATH="$work/tools${PYTHONPATH:+:$PYTHONPATH}"
fi
"$PYTHON" -m shiv --site-packages "$work/site" --entry-point edge_vis.cli:main \
    --python '/usr/bin/env python3' --reproducible --compressed \
    --output-file "$out.tmp" >/dev/null
mv -f "$out.tmp" "$out"
"$PYTHON" "$out" --version >/dev/null
say "done: $out ($(du -h "$out" | cut -f1)), for $("$PYTHON" -c 'import platform, sys
print(f"Python {sys.version_info[0]}.{sys.version_info[1]} on {platform.machine()}")')"
