#!/usr/bin/env bash
# Every command-line flag that README.md, docs/*.md, deploy/*.md and deploy/'s scripts give a
# tool exists: the tool's --help (or its subcommand's) lists it. A flag belongs to a tool where
# the docs say so without doubt:
#   - a command: a code span (`...`, across line breaks too), a line of a fenced code block
#     with its continuation lines (after a trailing \, or indented), or an indented code line,
#     whose first word is probecast-NAME (or build/bin/probecast-NAME): every --flag in it is
#     NAME's, or NAME SUB's where the next word is one of NAME's subcommands;
#   - a tool's list item, "- **probecast-NAME ...**" down to the next item or blank line: every
#     --flag in its bold title and its code spans is NAME's (the subcommand's, where the span
#     starts with a subcommand's name; else any of NAME's or its subcommands').
# Flags elsewhere (prose that names no tool, tables) are not checked. A failure names the doc
# file and line, the tool and the flag.
#
#   tests/docs_flags_exist.sh BIN_DIR SOURCE_DIR WORK_DIR
set -uo pipefail
bin=$1
src=$2
work=$3
rm -rf "$work"
mkdir -p "$work"

# mentions FILE...: one line per flag a doc gives a tool, "FILE:LINE TOOL MODE WORD FLAG", where
# MODE is cmd or item and WORD the word after the tool's name (cmd) or the span's first word
# (item), "-" where there is none.
mentions() {
  awk '
    function reset_span() { open = 0; span = "" }
    # A command or span, as "@LINE word word ...": attribute its flags (see the header).
    function attribute(text, item_tool,   n, w, i, line, first, second, tool, mode, word, f, rest) {
      n = split(text, w, /[ \t]+/)
      # The first word, and the one after it (a subcommand, maybe).
      first = ""; second = ""
      for (i = 1; i <= n && second == ""; i++) {
        if (w[i] == "" || w[i] ~ /^@[0-9]+$/) continue
        if (first == "") first = w[i]; else second = w[i]
      }
      word = "-"
      if (first ~ /^(build\/bin\/)?probecast-[a-z]+$/) {
        tool = first; sub(/^build\/bin\//, "", tool); mode = "cmd"
        if (second != "" && second !~ /^-/) word = second
      } else if (item_tool != "") {
        tool = item_tool; mode = "item"
        if (first != "" && first !~ /^-/) word = first
      } else return
      for (i = 1; i <= n; i++) {
        if (w[i] ~ /^@[0-9]+$/) { line = substr(w[i], 2); continue }
        rest = w[i]
        while (match(rest, /(^|[^A-Za-z0-9_-])--[a-z0-9][a-z0-9-]*/)) {
          f = substr(rest, RSTART, RLENGTH); sub(/^[^-]+/, "", f)
          print FILENAME ":" line, tool, mode, word, f
          rest = substr(rest, RSTART + RLENGTH)
        }
      }
    }
    FNR == 1 { reset_span(); fence = 0; cmd = ""; item = "" }
    /^[ \t]*```/ { fence = !fence; cont = 0; if (cmd != "") attribute(cmd, ""); cmd = ""; next }
    fence {
      line = $0; sub(/[ \t]#.*$/, "", line)
      if (line ~ /^[ \t]*(build\/bin\/)?probecast-[a-z]/) {
        if (cmd != "") attribute(cmd, "")
        cmd = "@" FNR " " line
      } else if (cmd != "" && (cont || line ~ /^[ \t]/)) {
        cmd = cmd " @" FNR " " line
      } else {
        if (cmd != "") attribute(cmd, ""); cmd = ""
      }
      cont = (line ~ /\\[ \t]*$/)
      next
    }
    # Outside code blocks.
    /^[ \t]*$/ || /^#/ { reset_span(); item = ""; next }
    /^[ \t]*[-*] / {
      item = ""
      if (match($0, /^[ \t]*[-*] \*\*(build\/bin\/)?probecast-[a-z]+[^*]*\*\*/)) {
        title = substr($0, RSTART, RLENGTH); gsub(/^[ \t]*[-*] |\*\*/, "", title)
        split(title, t, " "); item = t[1]; sub(/^build\/bin\//, "", item)
        attribute("@" FNR " " title, "")
      }
    }
    /^    +(build\/bin\/)?probecast-[a-z]/ && !open && !/`/ { attribute("@" FNR " " $0, ""); next }
    {
      n = split($0, piece, "`")
      for (i = 1; i <= n; i++) {
        if (i > 1) {
          if (open) { attribute(span, item); reset_span() } else { open = 1; span = "" }
        }
        if (open) span = span " @" FNR " " piece[i]
      }
    }
  ' "$@"
}

# options TOOL [SUB]: the option names that `TOOL [SUB] --help` lists, one a line.
options() {
  "$bin/$1" ${2:+"$2"} --help 2>&1 | grep -oE '^ +-[^ ]+' | tr -d ' ' | tr ',' '\n' |
    sed -E 's/[={\[].*$//' | grep -E '^--'
}

# subcommands TOOL: the subcommand names TOOL's --help lists.
subcommands() {
  "$bin/$1" --help 2>&1 | awk '/^[A-Za-z]+:/ { in_subs = (toupper($0) ~ /^SUBCOMMANDS:/); next }
                               in_subs && /^  [a-z]/ { print $1 }'
}

cd "$src" || exit 1
# deploy/'s scripts name the tools as commands (shell functions probecast-NAME): read as code
# blocks, with "$bin/" dropped, every flag given to a tool there is checked too.
deploy_docs=()
for f in deploy/*; do
  [[ -f $f && $f != *.md ]] || continue
  mkdir -p "$work/deploy"
  { echo '```'; sed -E 's#"?\$\{?bin\}?/(probecast-[a-z]+)"?#\1#g' "$f"; echo '```'; } >"$work/$f.md"
  deploy_docs+=("$work/$f.md")
done
mentions README.md docs/*.md deploy/*.md "${deploy_docs[@]}" >"$work/mentions"
checked=0
failed=0
while read -r where tool mode word flag; do
  if [[ ! -x $bin/$tool ]]; then
    echo "FAIL: $where: $tool (with $flag) is not a tool in $bin"
    failed=1
    continue
  fi
  if [[ ! -f $work/$tool.subs ]]; then
    subcommands "$tool" >"$work/$tool.subs"
    options "$tool" >"$work/$tool.opts"
    cp "$work/$tool.opts" "$work/$tool.all"
    while read -r s; do
      options "$tool" "$s" >"$work/$tool.$s.opts"
      cat "$work/$tool.$s.opts" >>"$work/$tool.all"
    done <"$work/$tool.subs"
  fi
  # Which help must list the flag: the subcommand's, the tool's, or (a tool's list item that
  # names no subcommand) any of them.
  if [[ $word != - ]] && grep -qxF -- "$word" "$work/$tool.subs"; then
    list=$tool.$word.opts
    help="$tool $word --help"
  elif [[ $mode == item && -s $work/$tool.subs ]]; then
    list=$tool.all
    help="$tool --help (or a subcommand's)"
  else
    list=$tool.opts
    help="$tool --help"
  fi
  checked=$((checked + 1))
  if ! grep -qxF -- "$flag" "$work/$list"; then
    echo "FAIL: $where: $flag is given to $tool, but \`$help\` does not list it"
    failed=1
  fi
done <"$work/mentions"

if ((checked == 0)); then
  echo "FAIL: no tool flags found in README.md and docs/*.md (the rule above finds none)"
  exit 1
fi
if ((failed)); then exit 1; fi
echo "ok: the $checked tool flags README.md, docs/*.md and deploy/ name are in the tools' --help"
