# Sourced by the test scripts that run the `host-sim` binary: `host_sim_bin` builds it as the
# test stage does (`cargo test --workspace`: the test profile, opt-level 2 with debug
# assertions, the workspace's features unified) and prints its path. After that stage the
# build is a no-op, so CI compiles the host's dependency tree once for the tests and the
# front ends, not a second time in the release profile.
host_sim_bin() {
    cargo test --workspace --no-run -q >&2
    local dir
    dir="$(cargo metadata --format-version 1 --no-deps |
        python3 -c 'import json, sys; print(json.load(sys.stdin)["target_directory"])')"
    echo "$dir/debug/host-sim"
}
