#!/usr/bin/env bash
# Prepare a Debian machine to run and test edge-vis; safe to run again at any time.
#
#   bash scripts/setup.sh [-v] [--secure]
#
# 1. Debian packages that are missing: libudt-dev (UDT library the udt4py binding links
#    against), a C++ compiler, and a Python >= 3.11 with venv and headers. `apt-get update`
#    runs only when something must be installed; root or sudo is needed only then.
# 2. A virtual environment in .venv (or $EDGE_VIS_VENV), created if absent or broken.
# 3. udt4py 1.2, built from source against the system libudt. Its 2014 setup.py needs
#    Cython at build time but does not declare it, so it is built without build isolation
#    after installing Cython, wheel and setuptools into the venv.
# 4. edge-vis itself, editable, with the dds, serial, udt and test extras. Skipped when
#    pyproject.toml has not changed since the last successful run.
#
# --secure (or EDGE_VIS_SECURE=1) prepares a second environment for DDS Security instead:
# Debian's Cyclone DDS 0.10.2 C library, which ships the security plugins (the PyPI wheel
# has none), and the cyclonedds 0.10.2 Python binding built from source against it, in
# .venv-secure (or $EDGE_VIS_VENV), with everything else as above. The default .venv keeps
# the PyPI binding, so both bindings stay tested side by side (scripts/test.sh).
#
# Output is quiet unless something fails (then the tail of the log is shown) or -v /
# EDGE_VIS_SETUP_VERBOSE=1 is given. $EDGE_VIS_PYTHON selects the interpreter.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VERBOSE="${EDGE_VIS_SETUP_VERBOSE:-0}"
SECURE="${EDGE_VIS_SECURE:-0}"
for arg in "$@"; do
    case "$arg" in
        -v|--verbose) VERBOSE=1 ;;
        --secure) SECURE=1 ;;
        *) echo "setup: unknown option $arg (expected -v, --secure)" >&2; exit 2 ;;
    esac
done
if [[ "$SECURE" == 1 ]]; then
    VENV="${EDGE_VIS_VENV:-$ROOT/.venv-secure}"
else
    VENV="${EDGE_VIS_VENV:-$ROOT/.venv}"
fi
# the Cyclone DDS release Debian 12 ships with its security plugins, and its Python binding
SECURE_CYCLONE="0.10.2"
MIN_PY="3.11"
EXTRAS="dds,serial,udt,test"
BUILD_TOOLS=("Cython>=3,<4" "wheel" "setuptools>=68")
UDT4PY="udt4py==1.2"
LOG="$(mktemp "${TMPDIR:-/tmp}/edge-vis-setup.XXXXXX.log")"
trap 'rm -f "$LOG"' EXIT

say() { echo "setup: $*" >&2; }
die() { echo "setup: ERROR: $*" >&2; exit 1; }

# run DESCRIPTION CMD...: run quietly into the log; on failure show its tail and stop.
run() {
    local what="$1"; shift
    if [[ "$VERBOSE" == 1 ]]; then
        "$@" 2>&1 | tee -a "$LOG" >&2 || die "$what failed (command: $*)"
        return 0
    fi
    if ! "$@" >>"$LOG" 2>&1; then
        echo "setup: ERROR: $what failed (command: $*). Last lines of output:" >&2
        grep -v "^WARNING: Location .* is ignored" "$LOG" | tail -n 40 | sed 's/^/  | /' >&2
        exit 1
    fi
}

# One set-up at a time for this tree: two scripts started together must not race on .venv.
if command -v flock >/dev/null 2>&1; then
    LOCK="${TMPDIR:-/tmp}/edge-vis-setup-$(printf '%s' "$VENV" | cksum | cut -d' ' -f1).lock"
    exec 9>"$LOCK"
    flock 9
fi

# ---- 1. Debian packages ------------------------------------------------------------------
deb_installed() { dpkg-query -W -f='${Status}' "$1" 2>/dev/null | grep -q "ok installed"; }

py_ok() {  # interpreter is >= MIN_PY
    "$1" -c "import sys; sys.exit(sys.version_info < (${MIN_PY/./, }))" >/dev/null 2>&1
}

find_python() {
    local c
    for c in ${EDGE_VIS_PYTHON:-} python3 python3.13 python3.12 python3.11; do
        if command -v "$c" >/dev/null 2>&1 && py_ok "$c"; then command -v "$c"; return 0; fi
    done
    return 1
}

NEED=()
PY="$(find_python || true)"
if [[ -z "$PY" ]]; then
    NEED+=(python3 python3-venv python3-dev)
else
    # Debian splits venv/ensurepip and the C headers out of the interpreter package.
    pyver="$("$PY" -c 'import sys; print(f"{sys.version_info[0]}.{sys.version_info[1]}")')"
    if ! "$PY" -c "import venv, ensurepip" >/dev/null 2>&1; then
        NEED+=("python${pyver}-venv")
    fi
    inc="$("$PY" -c 'import sysconfig; print(sysconfig.get_paths()["include"])')"
    [[ -f "$inc/Python.h" ]] || NEED+=("python${pyver}-dev")
fi
command -v c++ >/dev/null 2>&1 || command -v g++ >/dev/null 2>&1 || NEED+=(g++)
if command -v dpkg-query >/dev/null 2>&1; then
    deb_installed libudt-dev || NEED+=(libudt-dev)
elif [[ ! -f /usr/include/udt/udt.h ]]; then
    die "UDT headers (/usr/include/udt/udt.h) not found and this is not a Debian system: install libudt 4.11 development files by hand"
fi
if [[ "$SECURE" == 1 ]]; then
    command -v dpkg-query >/dev/null 2>&1 || die "--secure needs Debian's Cyclone DDS packages (dpkg/apt)"
    # libddsc0debian: the C library with libdds_security_{auth,crypto,ac}; -dev: the headers
    # the binding compiles against; -tools: idlc, which the binding's build looks for
    for pkg in libddsc0debian cyclonedds-dev cyclonedds-tools gcc; do
        deb_installed "$pkg" || NEED+=("$pkg")
    done
fi

if ((${#NEED[@]})); then
    command -v apt-get >/dev/null 2>&1 || die "missing ${NEED[*]} and no apt-get to install them"
    SUDO=()
    if [[ "$(id -u)" != 0 ]]; then
        command -v sudo >/dev/null 2>&1 || die "missing Debian packages ${NEED[*]}: run as root or install sudo"
        if [[ -t 0 ]]; then SUDO=(sudo); else SUDO=(sudo -n); fi
    fi
    say "installing Debian packages: ${NEED[*]}"
    export DEBIAN_FRONTEND=noninteractive
    run "apt-get update" "${SUDO[@]}" apt-get update -q
    run "apt-get install ${NEED[*]}" "${SUDO[@]}" apt-get install -y -q --no-install-recommends "${NEED[@]}"
    PY="$(find_python || true)"
    [[ -n "$PY" ]] || die "no Python >= $MIN_PY found after installing python3"
fi

# ---- 2. virtual environment --------------------------------------------------------------
VPY="$VENV/bin/python"
relocated() {  # a venv copied or cloned from elsewhere: its scripts run the other venv
    local first
    first="$(head -n 1 "$VENV/bin/pip" 2>/dev/null || true)"
    [[ "$first" == "#!/"*"/bin/python"* && "$first" != "#!$VENV/bin/python"* ]]
}
if [[ -e "$VENV" ]] && ! { [[ -x "$VPY" ]] && py_ok "$VPY" && ! relocated; }; then
    say "$VENV is broken, older than Python $MIN_PY or was made for another directory: recreating it"
    rm -rf "$VENV"
fi
if [[ ! -x "$VPY" ]]; then
    say "creating $VENV with $("$PY" --version 2>&1)"
    run "creating the virtual environment" "$PY" -m venv "$VENV"
fi
PIP=("$VPY" -m pip --disable-pip-version-check)

# ---- 3. udt4py (native binding to libudt) ------------------------------------------------
if ! "$VPY" -c "import udt4py" >/dev/null 2>&1; then
    say "building udt4py against the system libudt (about 20 s)"
    run "installing build tools ${BUILD_TOOLS[*]}" "${PIP[@]}" install -q "${BUILD_TOOLS[@]}"
    run "building $UDT4PY" "${PIP[@]}" install -q --no-build-isolation "$UDT4PY"
    "$VPY" -c "import udt4py" >/dev/null 2>&1 || die "udt4py installed but does not import"
fi

# ---- 3a. the lanes' congestion control (links/udt/udt_cc.cpp) -----------------------------
# A UDT congestion control class of ours, which the adaptive lanes switch to pacing by
# their rate cap alone; built against the system libudt into the venv, again whenever the
# source is newer. links/udt/udt_cc.py falls back to libudt's own control without it.
CC_SRC="$ROOT/links/udt/udt_cc.cpp"
CC_LIB="$VENV/lib/edge-vis/libedge_udt_cc.so"
if [[ ! -f "$CC_LIB" || "$CC_SRC" -nt "$CC_LIB" ]]; then
    CXX="$(command -v c++ || command -v g++)"
    mkdir -p "$(dirname "$CC_LIB")"
    run "building $CC_LIB" "$CXX" -std=c++17 -O2 -Wall -shared -fPIC -o "$CC_LIB.tmp" \
        "$CC_SRC" -ludt
    mv -f "$CC_LIB.tmp" "$CC_LIB"
fi
"$VPY" -c "import ctypes, sys; ctypes.CDLL(sys.argv[1])" "$CC_LIB" >/dev/null 2>&1 \
    || die "$CC_LIB was built but does not load"

# ---- 3b. (--secure) the Cyclone DDS binding built against Debian's library ---------------
secure_binding_ok() {  # the 0.10.2 binding, loading Debian's libddsc (not a bundled one)
    "$VPY" - "$SECURE_CYCLONE" <<'EOF' >/dev/null 2>&1
import sys
from importlib.metadata import version
import cyclonedds.core  # noqa: F401  loads libddsc
sys.exit(version("cyclonedds") != sys.argv[1])
EOF
}
if [[ "$SECURE" == 1 ]] && ! secure_binding_ok; then
    say "building the cyclonedds $SECURE_CYCLONE binding against Debian's Cyclone DDS (about 10 s)"
    # its setup.py wants $CYCLONEDDS_HOME/{include,bin,lib/libddsc.so}: Debian spreads them
    # over /usr/include, /usr/bin and the multiarch library directory
    # kept in the venv: the binding records <home>/lib/libddsc.so as its last-resort path
    home="$VENV/cyclonedds-home"
    rm -rf "$home" && mkdir -p "$home"
    multiarch="$(dpkg-architecture -qDEB_HOST_MULTIARCH 2>/dev/null || gcc -print-multiarch)"
    ln -s /usr/include "$home/include"
    ln -s /usr/bin "$home/bin"
    ln -s "/usr/lib/$multiarch" "$home/lib"
    [[ -e "$home/lib/libddsc.so" ]] \
        || die "Debian's libddsc.so not found in /usr/lib/$multiarch (is cyclonedds-dev installed?)"
    "${PIP[@]}" uninstall -y -q cyclonedds >>"$LOG" 2>&1 || true
    # --no-cache-dir: never reuse a wheel built against another library
    run "building cyclonedds==$SECURE_CYCLONE" env CYCLONEDDS_HOME="$home" \
        "${PIP[@]}" install -q --no-cache-dir --no-binary cyclonedds "cyclonedds==$SECURE_CYCLONE"
    secure_binding_ok \
        || die "cyclonedds $SECURE_CYCLONE built but does not import against Debian's libddsc"
fi

# ---- 4. edge-vis, editable, with extras --------------------------------------------------
STAMP="$VENV/.edge-vis-setup"
want="$(cksum <"$ROOT/pyproject.toml" | cut -d' ' -f1) $ROOT $EXTRAS secure=$SECURE"
installed_here() {  # edge_vis imports from this tree and every extra's package imports
    "$VPY" - "$ROOT" <<'EOF' >/dev/null 2>&1
import pathlib, sys
import cyclonedds, serial, udt4py, pytest, hypothesis, construct, mypy  # noqa: F401
import edge_vis
sys.exit(pathlib.Path(edge_vis.__file__).resolve().parent != pathlib.Path(sys.argv[1]) / "edge_vis")
EOF
}
if [[ "$(cat "$STAMP" 2>/dev/null)" != "$want" ]] || ! installed_here \
        || [[ ! -x "$VENV/bin/edge-vis" || ! -x "$VENV/bin/ruff" ]]; then
    say "installing edge-vis (editable) with extras [$EXTRAS]"
    run "pip install -e .[$EXTRAS]" "${PIP[@]}" install -q -e "${ROOT}[${EXTRAS}]"
    installed_here || die "edge-vis installed but 'import edge_vis' does not resolve to $ROOT"
    printf '%s' "$want" >"$STAMP"
fi

if [[ "$SECURE" == 1 ]]; then
    secure_binding_ok || die "installing edge-vis replaced the cyclonedds $SECURE_CYCLONE binding"
    say "ready: $VENV ($("$VPY" --version 2>&1), cyclonedds $SECURE_CYCLONE with DDS Security)"
else
    say "ready: $VENV ($("$VPY" --version 2>&1))"
fi
