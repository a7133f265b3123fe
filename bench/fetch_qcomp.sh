#!/usr/bin/env bash
# Refresh bench/qcomp/ (the QComp DTMC models the scale benchmark runs) from the
# Quantitative Verification Benchmark Set, https://github.com/ahartmanns/qcomp
# (data under CC-BY 4.0; see bench/qcomp/README.md for the attribution).
#
#   bench/fetch_qcomp.sh [QCOMP_GIT_DIR_OR_CHECKOUT]
#
# With an argument, the files are read from that repository (a bare git dir or a
# checkout) at its HEAD; without one, the repository is cloned shallowly into a
# temporary folder first (needs network access to GitHub).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
target="$here/qcomp"
files=(
  brp/brp.prism brp/brp.props
  crowds/crowds.prism crowds/crowds.props
  egl/egl.prism egl/egl.props
  herman/herman.17.prism herman/herman.19.prism herman/herman.21.prism herman/herman.props
  leader_sync/leader_sync.5-4.prism leader_sync/leader_sync.props
  nand/nand.prism nand/nand.props
)
source_repo="${1:-}"
if [[ -z "$source_repo" ]]; then
  tmp="$(mktemp -d)"
  trap 'rm -rf "$tmp"' EXIT
  git clone --quiet --depth 1 --filter=blob:none --sparse https://github.com/ahartmanns/qcomp "$tmp/qcomp"
  git -C "$tmp/qcomp" sparse-checkout set benchmarks/dtmc
  source_repo="$tmp/qcomp"
fi
if [[ -d "$source_repo/.git" ]]; then
  git_dir="$source_repo/.git"
else
  git_dir="$source_repo"
fi
for f in "${files[@]}"; do
  mkdir -p "$target/$(dirname "$f")"
  git --git-dir="$git_dir" show "HEAD:benchmarks/dtmc/$f" > "$target/$f"
done
echo "bench/qcomp/ refreshed from commit $(git --git-dir="$git_dir" rev-parse HEAD)"
