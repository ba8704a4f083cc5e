#!/usr/bin/env bash
# Shared set-up for scripts/demo, scripts/test and the benchmarks. Source it, do not run it.
#
# On a fresh machine it creates .venv from PyPI (pinned ROS 2 Jazzy wheels, numpy, scipy, pymunk,
# rerun-sdk, colcon), installs this package into it (console scripts in .venv/bin) and builds the
# `ros2 run` layout with colcon (install/coverage_ros/lib/coverage_ros/<exe>). Each step runs again
# only when its inputs changed, so the second run takes about a second.
#
# It also sets DDS defaults for every process started afterwards: discovery stays on this machine
# (ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST) unless the caller already chose something else.

# (no shell options here: the scripts that source it set -euo pipefail themselves, and a shell
# that sources it by hand keeps its own)

COVERAGE_ROS_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
export COVERAGE_ROS_ROOT
VENV="$COVERAGE_ROS_ROOT/.venv"
STAMPS="$VENV/.coverage_ros_stamps"

_say() { printf '[bootstrap] %s\n' "$*" >&2; }

_find_python() {
    local candidate
    for candidate in "${PYTHON:-}" python3.12 python3.11 python3; do
        [ -n "$candidate" ] || continue
        if command -v "$candidate" >/dev/null 2>&1 &&
            "$candidate" -c 'import sys; sys.exit(0 if sys.version_info >= (3, 11) else 1)' 2>/dev/null; then
            command -v "$candidate"
            return 0
        fi
    done
    return 1
}

_hash_of() { cat "$@" 2>/dev/null | sha256sum | cut -d' ' -f1; }

_stamp_ok() { [ -f "$STAMPS/$1" ] && [ "$(cat "$STAMPS/$1")" = "$2" ]; }

_stamp_set() { mkdir -p "$STAMPS" && printf '%s' "$2" > "$STAMPS/$1"; }

# The installer of the pinned dependencies, pinned too; COVERAGE_ROS_NO_UV=1: pip alone.
UV_VERSION="0.13.9"

# Installs the pinned requirement files given into the venv: with uv, which installs the same
# set as pip about five times faster (it links wheels from its cache and compiles byte-code in
# parallel), else or where uv fails with pip (uv reads no pip.conf: a machine that reaches PyPI
# only through a mirror set there). The installers' output goes to $VENV/uv-NAME.log and
# pip-NAME.log: some machines' pip.conf makes pip print many harmless warnings.
_install_requirements() {  # _install_requirements NAME FILE...
    local name="$1"; shift
    local args=() r
    for r in "$@"; do args+=(-r "$r"); done
    if _uv_ready; then
        if "$VENV/bin/uv" pip install --python "$VENV/bin/python" --compile-bytecode \
            "${args[@]}" >"$VENV/uv-$name.log" 2>&1; then
            return 0
        fi
        _say "uv could not install them (log: $VENV/uv-$name.log); trying pip"
    fi
    if ! "$VENV/bin/python" -m pip install --disable-pip-version-check "${args[@]}" \
        >"$VENV/pip-$name.log" 2>&1; then
        tail -n 25 "$VENV/pip-$name.log" >&2
        _say "error: pip install failed (network? full log: $VENV/pip-$name.log)"
        return 1
    fi
}

_uv_ready() {  # uv in the venv (installed with pip), unless turned off or not to be had
    [ -z "${COVERAGE_ROS_NO_UV:-}" ] || return 1
    [ -x "$VENV/bin/uv" ] && [ "$("$VENV/bin/uv" --version 2>/dev/null)" = "uv $UV_VERSION" ] &&
        return 0
    "$VENV/bin/python" -m pip install --disable-pip-version-check -q "uv==$UV_VERSION" \
        >"$VENV/uv-bootstrap.log" 2>&1 && [ -x "$VENV/bin/uv" ]
}

bootstrap_venv() {
    # Runtime and test/lint tools together: one requirement set, so no script ever reinstalls
    # another's (the dev tools are small).
    local extra_reqs=("$COVERAGE_ROS_ROOT/requirements-dev.txt")
    if [ ! -x "$VENV/bin/python" ]; then
        local py
        if ! py="$(_find_python)"; then
            _say "error: Python 3.11 or newer is needed (set PYTHON=/path/to/python3.11)"
            return 1
        fi
        _say "creating $VENV with $py"
        if ! "$py" -m venv "$VENV"; then
            _say "error: '$py -m venv' failed; on Debian/Ubuntu: sudo apt install python3-venv"
            return 1
        fi
        touch "$VENV/COLCON_IGNORE"
    fi
    local reqs=("$COVERAGE_ROS_ROOT/requirements.txt" "${extra_reqs[@]}")
    local want
    want="$(_hash_of "${reqs[@]}")"
    if ! _stamp_ok requirements "$want"; then
        _say "installing pinned dependencies from PyPI (first run: about 30 s with uv, 2 minutes" \
             "with pip)"
        _install_requirements install "${reqs[@]}" || return 1
        _stamp_set requirements "$want"
    fi
    # Editable install: console scripts in .venv/bin, sources used in place.
    want="$(_hash_of "$COVERAGE_ROS_ROOT/setup.py" "$COVERAGE_ROS_ROOT/setup.cfg")"
    if ! _stamp_ok editable "$want" || [ ! -x "$VENV/bin/world_node" ]; then
        _say "installing coverage_ros into .venv (editable)"
        if ! "$VENV/bin/python" -m pip install --disable-pip-version-check --no-deps \
            --no-build-isolation -e "$COVERAGE_ROS_ROOT" >"$VENV/pip-editable.log" 2>&1; then
            tail -n 25 "$VENV/pip-editable.log" >&2
            _say "error: installing coverage_ros into .venv failed (log: $VENV/pip-editable.log)"
            return 1
        fi
        _stamp_set editable "$want"
    fi
    # Byte-code of the sources, as a wheel's install writes it: where PYTHONDONTWRITEBYTECODE is
    # set, every process would compile the modules it imports again (~30 ms a coverage-plan run).
    # Up-to-date files are skipped.
    "$VENV/bin/python" -m compileall -q -j 0 "$COVERAGE_ROS_ROOT/coverage_ros" >/dev/null 2>&1 || true
}

bootstrap_colcon() {
    # The `ros2 run` layout. --symlink-install links the Python sources, so only changes to the
    # package metadata, entry points or shipped config need a rebuild.
    local want
    want="$(cd "$COVERAGE_ROS_ROOT" && _hash_of setup.py setup.cfg package.xml resource/coverage_ros \
        <(ls config config/worlds 2>/dev/null))"
    if ! _stamp_ok colcon "$want" || [ ! -x "$COVERAGE_ROS_ROOT/install/coverage_ros/lib/coverage_ros/world_node" ]; then
        _say "building the ros2 run layout with colcon (install/coverage_ros)"
        (
            cd "$COVERAGE_ROS_ROOT"
            rm -rf build/coverage_ros install/coverage_ros
            PATH="$VENV/bin:$PATH" "$VENV/bin/colcon" --log-base log build --paths . \
                --symlink-install --build-base build --install-base install \
                --event-handlers console_cohesion- summary- >/dev/null
        ) || { _say "error: colcon build failed; see $COVERAGE_ROS_ROOT/log/latest_build"; return 1; }
        touch "$COVERAGE_ROS_ROOT/build/COLCON_IGNORE" "$COVERAGE_ROS_ROOT/install/COLCON_IGNORE" \
            "$COVERAGE_ROS_ROOT/log/COLCON_IGNORE" 2>/dev/null || true
        _stamp_set colcon "$want"
    fi
}

bootstrap_env() {
    # DDS stays on this machine unless the user explicitly chose otherwise.
    export ROS_AUTOMATIC_DISCOVERY_RANGE="${ROS_AUTOMATIC_DISCOVERY_RANGE:-LOCALHOST}"
    export RMW_IMPLEMENTATION="${RMW_IMPLEMENTATION:-rmw_fastrtps_cpp}"
    export PATH="$VENV/bin:$PATH"
    # Make the package visible to the ament index, as `source install/setup.bash` would.
    case ":${AMENT_PREFIX_PATH:-}:" in
        *":$COVERAGE_ROS_ROOT/install/coverage_ros:"*) ;;
        *) export AMENT_PREFIX_PATH="$COVERAGE_ROS_ROOT/install/coverage_ros${AMENT_PREFIX_PATH:+:$AMENT_PREFIX_PATH}" ;;
    esac
    export PYTHONUNBUFFERED=1
}

_apt_install() {  # _apt_install WHAT PACKAGE...: Debian packages, when root with apt-get
    local what="$1"; shift
    [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null || {
        _say "warning: $* missing and cannot be installed here (needs root and apt-get): $what"
        return 0; }
    _say "installing $* (Debian packages, $what)"
    if ! timeout 900 apt-get install -y -q "$@" >/dev/null 2>&1; then
        timeout 600 apt-get update -q >/dev/null 2>&1 || true
        timeout 900 apt-get install -y -q "$@" >/dev/null 2>&1 ||
            _say "warning: could not install $*; $what will fail"
    fi
}

bootstrap_tools() {
    # nftables: the lossy-link tests and scripts/bench_faults drop packets inside a network
    # namespace with it (this kernel has no netem).
    command -v nft >/dev/null 2>&1 || _apt_install "for the lossy-link tests" nftables
    # Chromium and its WebDriver: the test that loads --serve-web's viewer in a headless browser.
    { command -v chromium >/dev/null 2>&1 && command -v chromedriver >/dev/null 2>&1; } ||
        _apt_install "for the web viewer test" chromium chromium-driver
}

_build_interface() {  # _build_interface NAME: interfaces/NAME into the venv
    local name="$1"
    local build="$COVERAGE_ROS_ROOT/build/interfaces/$name"
    rm -rf "$build"
    mkdir -p "$(dirname "$build")"
    (
        set -e
        export PATH="$VENV/bin:$PATH" CMAKE_PREFIX_PATH="$VENV" AMENT_PREFIX_PATH="$VENV"
        cmake -S "$COVERAGE_ROS_ROOT/interfaces/$name" -B "$build" -DCMAKE_BUILD_TYPE=Release \
            -DBUILD_TESTING=OFF -DCMAKE_INSTALL_PREFIX="$VENV" \
            -DPython3_EXECUTABLE="$VENV/bin/python" \
            -DCMAKE_PROJECT_INCLUDE="$COVERAGE_ROS_ROOT/interfaces/cmake/drop_missing_include_dirs.cmake" \
            > "$build.configure.log" 2>&1
        cmake --build "$build" -j2 > "$build.build.log" 2>&1
        cmake --install "$build" > "$build.install.log" 2>&1
    ) && "$VENV/bin/python" -c "import $name.msg" 2>/dev/null
}

# The interface packages' build cache: what the builds installed into a venv, kept per inputs
# (sources, pinned wheels, this script, Python, compiler) so that another clone's venv (a CI
# checkout) gets it without building. Off with COVERAGE_ROS_NO_BUILD_CACHE=1.
_interfaces_cache() {  # _interfaces_cache SOURCES_HASH: the cache folder of these inputs
    local key
    key="$( { printf '%s\n' "$1"
              cat "$COVERAGE_ROS_ROOT/requirements.txt" "$COVERAGE_ROS_ROOT/scripts/bootstrap.sh"
              "$VENV/bin/python" -c 'import platform, sys; print(sys.version, platform.machine())'
              g++ --version 2>/dev/null | head -1
            } | sha256sum | cut -d' ' -f1)"
    printf '%s' "${XDG_CACHE_HOME:-$HOME/.cache}/coverage_ros/interfaces/$key"
}

_restore_interfaces() {  # _restore_interfaces DIR: the cached files into the venv, paths ours
    local dir="$1" old
    [ -f "$dir/files.tar" ] && [ -f "$dir/prefix" ] || return 1
    old="$(cat "$dir/prefix")"
    tar -C "$VENV" -xf "$dir/files.tar" || return 1
    if [ "$old" != "$VENV" ]; then  # (a few text files name the venv they were built for)
        (cd "$VENV" && tar -tf "$dir/files.tar" | while IFS= read -r f; do
            if [ -f "$f" ] && grep -qIF "$old" "$f"; then sed -i "s|$old|$VENV|g" "$f"; fi
        done)
    fi
    "$VENV/bin/python" -c "import tf2_msgs.msg, coverage_msgs.msg" 2>/dev/null
}

_store_interfaces() {  # _store_interfaces DIR: what the builds installed (their manifests)
    local dir="$1" tmp m
    mkdir -p "$(dirname "$dir")" 2>/dev/null || return 0
    tmp="$(mktemp -d "$(dirname "$dir")/.new-XXXXXX")" || return 0
    if for m in "$COVERAGE_ROS_ROOT"/build/interfaces/*/install_manifest.txt; do
            cat "$m"; echo
        done | sed -n "s|^$VENV/||p" | tar -C "$VENV" -cf "$tmp/files.tar" -T - &&
        printf '%s' "$VENV" > "$tmp/prefix"; then
        # (-T: where another set-up stored the same meanwhile, keep its folder as it is)
        { rm -rf "$dir" && mv -T "$tmp" "$dir"; } 2>/dev/null || true
    fi
    rm -rf "$tmp"
}

bootstrap_interfaces() {
    # The interface packages in interfaces/, built with the rosidl generators and ament_cmake
    # wheels, gcc and cmake, and installed into the venv (no sourcing needed afterwards):
    # coverage_msgs (the stack's own messages; required) and tf2_msgs (/tf and /tf_static; not
    # on PyPI - without it the world node publishes no /tf).
    local want
    want="$(cd "$COVERAGE_ROS_ROOT" && _hash_of requirements-interfaces.txt \
        interfaces/*/package.xml interfaces/*/CMakeLists.txt interfaces/*/msg/*.msg \
        interfaces/cmake/*.cmake)"
    if _stamp_ok interfaces "$want" && "$VENV/bin/python" -c "import tf2_msgs.msg, coverage_msgs.msg" 2>/dev/null; then
        return 0
    fi
    local cache=""
    if [ -z "${COVERAGE_ROS_NO_BUILD_CACHE:-}" ]; then
        cache="$(_interfaces_cache "$want")"
        if _restore_interfaces "$cache"; then
            _say "coverage_msgs and tf2_msgs into .venv from the build cache ($cache)"
            _stamp_set interfaces "$want"
            return 0
        fi
    fi
    if ! command -v cmake >/dev/null 2>&1 || ! command -v g++ >/dev/null 2>&1; then
        if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
            _say "installing cmake and g++ (Debian packages, to build the interface packages)"
            timeout 900 apt-get install -y -q cmake g++ >/dev/null 2>&1 || true
        fi
    fi
    _say "building coverage_msgs and tf2_msgs into .venv (first run: about a minute)"
    if ! _install_requirements interface-tools "$COVERAGE_ROS_ROOT/requirements-interfaces.txt"
    then
        _say "error: installing the interface build tools failed"
        return 1
    fi
    if ! _build_interface coverage_msgs; then
        _say "error: building coverage_msgs failed (logs: build/interfaces/coverage_msgs.*.log)"
        return 1
    fi
    if ! _build_interface tf2_msgs; then
        _say "warning: building tf2_msgs failed (logs: build/interfaces/tf2_msgs.*.log); the world node will publish no /tf"
        return 0
    fi
    # (the key again: the compiler may have been installed above)
    [ -z "$cache" ] || _store_interfaces "$(_interfaces_cache "$want")"
    _stamp_set interfaces "$want"
}

bootstrap_all() {
    bootstrap_venv
    bootstrap_colcon
    bootstrap_tools
    bootstrap_interfaces
    bootstrap_env
}
