#!/usr/bin/env bash
# The libraries as dependencies of another project (the end of `make test`): a crate outside the
# workspace that depends by path on every libtorch-free library crate is resolved afresh (no copy
# of the workspace's Cargo.lock: the newest version each requirement allows), built without
# libtorch, and runs scripts/downstream-check/main.rs through their public APIs (a grid, a
# registration, a labelled render of a fixture scan, a metric).
#
# DOWNSTREAM_TARGET_DIR: its build folder (default: the workspace's target/, which holds it
# beside the workspace's own build). CARGO: the cargo to run.
set -euo pipefail

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cargo="${CARGO:-cargo}"
start=$SECONDS
crate="$(mktemp -d "${TMPDIR:-/tmp}/ipdf-downstream.XXXXXX")"
trap 'rm -rf "$crate"' EXIT
case "$crate/" in
"$root"/*)
    echo "downstream-check: $crate is inside the workspace; set TMPDIR elsewhere" >&2
    exit 1
    ;;
esac

# Library crates, each by path (TOML literal strings: the path as it is).
libraries=(so3-grid registration metrics depth-render examples/bop-dataset examples/synth-data
    examples/pseudo-label)
{
    cat <<'EOF'
[package]
name = "ipdf-downstream-check"
version = "0.0.0"
edition = "2024"
publish = false

[dependencies]
EOF
    for folder in "${libraries[@]}"; do
        name="$(sed -n 's/^name = "\(.*\)"$/\1/p' "$root/$folder/Cargo.toml" | head -n 1)"
        echo "$name = { path = '$root/$folder' }"
    done
    # What the program itself names, as a user of the libraries would ask for it.
    cat <<'EOF'
nalgebra = "0.35"
rand = "0.10"
rand_chacha = "0.10"

# Unoptimised, as a user's first `cargo run` builds them, but without debug information for
# the libraries: the fresh resolution builds most of them again whatever the profile, and at
# -O0 that took 139 s of the check where -O3 took 346 s on 2 cores (the labelling included).
[profile.dev]
debug = "line-tables-only"

[profile.dev.package."*"]
debug = false
EOF
} >"$crate/Cargo.toml"
mkdir "$crate/src"
cp "$root/scripts/downstream-check/main.rs" "$crate/src/main.rs"

# From inside the crate: cargo reads .cargo/config.toml from the current folder upwards, so the
# workspace's (which sets LIBTORCH) does not apply, and neither does an environment's.
cd "$crate"
unset LIBTORCH LIBTORCH_INCLUDE LIBTORCH_LIB LIBTORCH_USE_PYTORCH LIBTORCH_BYPASS_VERSION_CHECK
export CARGO_TARGET_DIR="${DOWNSTREAM_TARGET_DIR:-$root/target}"

"$cargo" generate-lockfile --quiet
tree="$("$cargo" tree -e normal,build --prefix none --format '{p}' | sed 's/ (\*)$//' | sort -u)"
if grep -q '^torch-sys ' <<<"$tree"; then
    echo "downstream-check: torch-sys is in the tree of the libtorch-free crates" >&2
    exit 1
fi
echo "downstream check: fresh resolution, $(wc -l <<<"$tree") packages, no torch-sys;" \
    "$(grep -E '^(glam|obvhs|parry3d|nalgebra) ' <<<"$tree" | cut -d' ' -f1,2 | paste -sd, - |
        sed 's/,/, /g')"
# Types of these cross between the libraries and their users: one version of each.
duplicated="$("$cargo" tree -d -e normal --depth 0 --prefix none --format '{p}' |
    grep -E '^(nalgebra|rand|rand_core|image|serde|obvhs|parry3d) ' | sort -u || true)"
if [[ -n "$duplicated" ]]; then
    echo "downstream-check: more than one version of:" >&2
    echo "$duplicated" >&2
    exit 1
fi

"$cargo" run --quiet -- "$root"
echo "downstream check: $((SECONDS - start)) s"
