#!/usr/bin/env bash
# `cmake --install` into a temporary prefix, component by component: the production tools
# (runtime) with units that name that prefix, sysusers.d and tmpfiles.d entries, man pages and
# completion; the mock bench (mockbench) apart. Then the installed pieces are used: the sample
# configuration passes --check-config, the bash completion completes, the man page has the
# commands.   install_layout.sh BUILD_DIR
set -euo pipefail
build=$1
# Under the build tree (the checks below look for /tmp in what is installed, less the prefix).
tmp=$(mktemp -d "$(cd "$build" && pwd)/install-test.XXXXXX")
trap 'rm -rf "$tmp"' EXIT
fail() { echo "install layout: $*" >&2; exit 1; }
p=$tmp/prefix
cmake --install "$build" --prefix "$p" --component runtime >/dev/null

for f in bin/fogctl libexec/fogbench/fogctl-fleet sbin/fogbenchd lib/systemd/system/fogbenchd.service lib/systemd/system/fogbenchd@.service \
         lib/sysusers.d/fogbench.conf lib/tmpfiles.d/fogbench.conf share/man/man1/fogctl.1 share/man/man8/fogbenchd.8 \
         share/bash-completion/completions/fogctl share/zsh/vendor-completions/_fogctl \
         share/doc/fogbench/fogbenchd.json.example share/doc/fogbench/daemon.md share/fogbench/profiles/exp1.profile share/fogbench/plans/paper.plan; do
  [[ -e $p/$f ]] || fail "$f not installed"
done
# Stripped by default (no symbol table, no line tables), whatever the build's -g1.
for f in bin/fogctl libexec/fogbench/fogctl-fleet sbin/fogbenchd; do
  readelf -S "$p/$f" | grep -q -e '\.symtab' -e '\.debug_line' && fail "$f installed with symbols or debug information"
done
# FOGBENCH_INSTALL_KEEP_SYMBOLS=1 keeps them (the build's line tables, for gdb).
k=$tmp/keep
FOGBENCH_INSTALL_KEEP_SYMBOLS=1 cmake --install "$build" --prefix "$k" --component runtime >/dev/null
readelf -S "$k/bin/fogctl" | grep -q '\.debug_line' || fail "FOGBENCH_INSTALL_KEEP_SYMBOLS=1: fogctl stripped anyway"
rm -rf "$k"
# The mock bench is not a production tool: not in the runtime component.
[[ ! -e $p/bin/fogbench-sim ]] || fail "fogbench-sim installed with the runtime component"

unit=$p/lib/systemd/system/fogbenchd.service
grep -qx "ExecStart=$p/sbin/fogbenchd --config $p/etc/fogbench/fogbenchd.json" "$unit" || fail "ExecStart does not name the prefix: $(grep ExecStart "$unit")"
grep -qx "Documentation=man:fogbenchd(8) file:$p/share/doc/fogbench/daemon.md" "$unit" || fail "Documentation: $(grep Documentation "$unit")"
grep -qx "Type=notify" "$unit" || fail "not Type=notify"
grep -q "^WatchdogSec=" "$unit" || fail "no WatchdogSec"
grep -q "/usr/sbin\|/usr/share" "$unit" && fail "the unit still names /usr: $(grep -n '/usr/' "$unit")"
grep -q "$p/sbin/fogbenchd --config $p/etc/fogbench/%i.json" "$p/lib/systemd/system/fogbenchd@.service" || fail "fogbenchd@: ExecStart"
grep -q "^u fogbench " "$p/lib/sysusers.d/fogbench.conf" || fail "sysusers.d: no fogbench user and group"
grep -q "^d /var/lib/fogbench " "$p/lib/tmpfiles.d/fogbench.conf" || fail "tmpfiles.d: no state directory"

example=$p/share/doc/fogbench/fogbenchd.json.example
# The prefix itself may lie under /tmp (a checkout there): look at what the file names besides it.
sed "s|$p||g" "$example" | grep -q "/tmp" && fail "the sample configuration points at /tmp (the unit has PrivateTmp)"
grep -q "\"$p/share/fogbench/profiles\"" "$example" || fail "sample profile_dir is not the prefix's"
"$p/sbin/fogbenchd" --check-config "$example" >/dev/null || fail "the sample configuration does not pass --check-config"

# The configuration the unit starts from is installed under etc/ from the sample when there is
# none, and an existing one is never overwritten (the install says it kept it).
config=$p/etc/fogbench/fogbenchd.json
[[ -f $config ]] || fail "etc/fogbench/fogbenchd.json not installed (the unit's ExecStart names it)"
cmp -s "$config" "$example" || fail "etc/fogbench/fogbenchd.json is not the sample configuration"
"$p/sbin/fogbenchd" --check-config "$config" >/dev/null || fail "the installed configuration does not pass --check-config"
echo '{"station edited": true}' > "$config"
again=$(cmake --install "$build" --prefix "$p" --component runtime)
[[ $(cat "$config") == '{"station edited": true}' ]] || fail "a second install overwrote etc/fogbench/fogbenchd.json"
[[ $again == *"Keeping: $config (it exists: never overwritten"* ]] || fail "a second install does not say it kept $config: $again"

# Every document the man pages' SEE ALSO names is installed (mock-bench.md with the mock bench, below).
see_also=$(sed -n '/^\.SH SEE ALSO/,$p' "$p/share/man/man1/fogctl.1")
named=$(grep -o '[a-z-]*\.md\|fogbenchd\.json\.example' <<<"$see_also" | sort -u)
[[ -n $named ]] || fail "fogctl.1's SEE ALSO names no document: $see_also"
for doc in $named; do
  [[ $doc == mock-bench.md || -e $p/share/doc/fogbench/$doc ]] || fail "SEE ALSO names $doc, not installed in share/doc/fogbench"
done

# The installed fogctl runs its fleet commands in the installed fogctl-fleet (its own usage error).
fleet_err=$("$p/bin/fogctl" fleet serials 2>&1 >/dev/null || true)
[[ $fleet_err == *"give the plant store with exactly one of --db"* ]] || fail "fogctl fleet does not reach libexec/fogbench/fogctl-fleet: $fleet_err"

grep -q '^\.TH FOGCTL 1' "$p/share/man/man1/fogctl.1" || fail "fogctl.1 has no .TH"
grep -q '^\.SS fogctl run start' "$p/share/man/man1/fogctl.1" || fail "fogctl.1 lacks run start"
grep -q -- '--check-config' "$p/share/man/man8/fogbenchd.8" || fail "fogbenchd.8 lacks --check-config"

# The bash completion, used as bash would.
complete_words() {
  bash -c 'source "$1"; shift; COMP_WORDS=("$@"); COMP_CWORD=$((${#COMP_WORDS[@]} - 1)); _fogctl; echo "${COMPREPLY[*]}"' _ \
    "$p/share/bash-completion/completions/fogctl" "$@"
}
[[ " $(complete_words fogctl ru) " == *" run "* ]] || fail "bash: 'fogctl ru' does not complete to run"
[[ " $(complete_words fogctl run st) " == *" start "* ]] || fail "bash: 'fogctl run st' does not complete to start"
[[ " $(complete_words fogctl run start --pro) " == *" --profile "* ]] || fail "bash: no --profile after run start"
[[ " $(complete_words fogctl fit --deci) " == *" --decimal-comma "* ]] || fail "bash: no --decimal-comma on fit"
if command -v zsh >/dev/null; then zsh -n "$p/share/zsh/vendor-completions/_fogctl" || fail "zsh: syntax"; fi

# The mock bench alone, with its man page; it says its version.
m=$tmp/mock
cmake --install "$build" --prefix "$m" --component mockbench >/dev/null
[[ -x $m/bin/fogbench-sim && -e $m/share/man/man1/fogbench-sim.1 ]] || fail "mockbench component incomplete"
[[ ! -e $m/bin/fogctl && ! -e $m/sbin/fogbenchd ]] || fail "the mockbench component installs production tools"
"$m/bin/fogbench-sim" --version | grep -q '^[0-9]' || fail "fogbench-sim --version"
[[ -e $m/share/doc/fogbench/mock-bench.md ]] || fail "mockbench: mock-bench.md (its man page's SEE ALSO) not installed"

# A build of named targets only (scripts/demo's `fogbenchd fogctl fogbench-sim`) does not make
# the man pages and completion (they are `all`'s): install makes them from the executables, the
# same files as the build's, and says so.
gen=$(cd "$build" && pwd)/generated
rm -f "$gen/fogctl.1" "$gen/fogctl.bash" "$gen/_fogctl" "$gen/fogbenchd.8" "$gen/fogbench-sim.1"
q=$tmp/partial
out=$(cmake --install "$build" --prefix "$q" --component runtime)
[[ $out == *"Generating: $gen/fogctl.1"* ]] || fail "install after a partial build does not say it makes fogctl.1: $out"
for f in share/man/man1/fogctl.1 share/man/man8/fogbenchd.8 share/bash-completion/completions/fogctl share/zsh/vendor-completions/_fogctl; do
  cmp -s "$p/$f" "$q/$f" || fail "after a partial build, $f is missing or differs from a full build's"
done
cmake --install "$build" --prefix "$q" --component mockbench >/dev/null
cmp -s "$m/share/man/man1/fogbench-sim.1" "$q/share/man/man1/fogbench-sim.1" || fail "after a partial build, fogbench-sim.1 is missing or differs"
ls "$gen"/*.tmp >/dev/null 2>&1 && fail "temporary files left in $gen: $(ls "$gen"/*.tmp)"
echo "install layout: ok"
