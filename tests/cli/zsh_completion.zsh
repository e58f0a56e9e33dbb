# fogctl's zsh completion used as zsh uses it (run by zsh_completion.sh): an interactive `zsh -f`
# in a pseudo-terminal (zsh/zpty) with the generated _fogctl on its fpath and compinit, keys
# typed into its line editor. A wrapped compadd records every match the completion offers; a key
# bound to a widget records the line after the completion. Checked against the command table:
# every command's subcommands are offered after it, `ru<TAB>` becomes `run `, and options come
# after `-`.
#   zsh -f zsh_completion.zsh DIR    (DIR holds _fogctl and `commands`, fogctl __generate's)
emulate -L zsh
setopt err_return no_unset
dir=$1
zmodload zsh/zpty
zmodload zsh/datetime
integer failures=0
fail() { print -r -- "FAIL: $*"; (( ++failures )); return 0 }

zpty z zsh -f -i
# Drains the terminal's output (so the shell never blocks writing) until FILE exists, at most
# 20 s; 1 when it did not come.
wait_for() {
  local file=$1 line
  local deadline=$(( EPOCHREALTIME + 20 ))
  while [[ ! -e $file ]]; do
    (( EPOCHREALTIME < deadline )) || return 1
    zpty -rt z line 2>/dev/null || sleep 0.02
  done
  return 0
}
# Setup, each step confirmed by a file before the next (typeahead is not relied upon).
step() {
  rm -f $dir/ok
  zpty -w z "$1; : >| $dir/ok"
  wait_for $dir/ok || { print -r -- "FAIL: the shell did not run: $1"; exit 1 }
}
step "PS1='> '; PROMPT_EOL_MARK=''; unsetopt beep"
step "fpath=($dir \$fpath); autoload -U compinit; compinit -u -D"
step "(( \$+_comps[fogctl] )) && [[ \$_comps[fogctl] == _fogctl ]] && : >| $dir/registered"
[[ -e $dir/registered ]] || fail "compinit did not register _fogctl for fogctl (#compdef)"
# Every match offered, one a line, into \$CAPTURE; compadd calls that only ask (-O, -A, -D) pass.
step 'compadd() { local a; for a in "$@"; do [[ $a == -- || $a == - ]] && break; [[ $a == -[OAD]* ]] && { builtin compadd "$@"; return } ; done; local -a __hits; builtin compadd -A __hits "$@"; (( $#__hits )) && print -rl -- $__hits >> $CAPTURE; builtin compadd "$@" }'
step "dumpbuf() { print -r -- \"<\$BUFFER>\" >| \$CAPTURE.line; BUFFER=''; }; zle -N dumpbuf; bindkey '^X' dumpbuf; CAPTURE=$dir/capture"

# Types TEXT, then TAB, then ^X; sets `line` to the line after the completion and `offered` to
# the matches offered.
typeset line
typeset -a offered
complete() {
  rm -f $dir/capture $dir/capture.line
  zpty -w -n z "$1"$'\t\x18'
  if ! wait_for $dir/capture.line; then
    fail "no answer completing '$1'"
    line='' offered=()
    return 0
  fi
  line=$(<$dir/capture.line)
  offered=(${(f)"$(<$dir/capture 2>/dev/null)"})
  return 0
}

# The command table: each command's subcommands.
typeset -A subs
typeset -a top
for c in ${(f)"$(<$dir/commands)"}; do
  w=(${=c})
  if (( $#w == 1 )); then top+=($c); else subs[$w[1]]+=" $w[2]"; fi
done
(( $#top > 10 )) || fail "the command table has only ${#top} commands"

# After `fogctl `: every top-level command.
complete "fogctl "
for c in $top; do (( ${offered[(Ie)$c]} )) || fail "'fogctl <TAB>' does not offer $c (offered: $offered)"; done
# After each command that has subcommands: all of them, and nothing of another command's.
for parent in ${(k)subs}; do
  complete "fogctl $parent "
  for s in ${=subs[$parent]}; do
    (( ${offered[(Ie)$s]} )) || fail "'fogctl $parent <TAB>' does not offer $s (offered: $offered)"
  done
  (( ${offered[(Ie)$parent]} )) && fail "'fogctl $parent <TAB>' offers $parent again"
done
# A unique prefix completes in the line.
complete "fogctl ru"
[[ $line == "<fogctl run >" ]] || fail "'fogctl ru<TAB>' gave $line, not <fogctl run >"
complete "fogctl run sta"
[[ $line == "<fogctl run start >" ]] || fail "'fogctl run sta<TAB>' gave $line, not <fogctl run start >"
# Options after `-`, the command's own: run start's --profile, fit's --decimal-comma.
complete "fogctl run start --pro"
[[ $line == "<fogctl run start --profile >" ]] || fail "'fogctl run start --pro<TAB>' gave $line (offered: $offered)"
complete "fogctl fit --deci"
[[ $line == "<fogctl fit --decimal-comma >" ]] || fail "'fogctl fit --deci<TAB>' gave $line (offered: $offered)"
complete "fogctl run start --"
(( ${offered[(Ie)--help]} )) || fail "'fogctl run start --<TAB>' does not offer --help (offered: $offered)"
(( ${offered[(Ie)--decimal-comma]} )) && fail "'fogctl run start --<TAB>' offers fit's --decimal-comma"

zpty -d z
(( failures == 0 )) && print "zsh completion: ok (${#top} commands, ${#subs} with subcommands)"
exit $(( failures ? 1 : 0 ))
