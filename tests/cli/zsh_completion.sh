#!/usr/bin/env bash
# The zsh completion of fogctl, generated from its command table (fogctl __generate zsh), tried
# in a real zsh (zsh_completion.zsh). Without zsh: SKIPPED (exit 77; Debian package zsh, which
# scripts/deps installs).
#   zsh_completion.sh FOGCTL
set -euo pipefail
fogctl=$1
if ! command -v zsh >/dev/null 2>&1; then
  echo "SKIPPED: zsh is not installed (Debian package: zsh): the zsh completion cannot be tried"
  exit 77
fi
tmp=$(mktemp -d /tmp/fogbench-zsh-XXXXXX)
trap 'rm -rf "$tmp"' EXIT
"$fogctl" __generate zsh >"$tmp/_fogctl"
"$fogctl" __generate commands >"$tmp/commands"
zsh -n "$tmp/_fogctl"
HOME=$tmp zsh -f "$(dirname "$0")/zsh_completion.zsh" "$tmp"
