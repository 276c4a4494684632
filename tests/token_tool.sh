#!/usr/bin/env bash
# probecast-token end to end: keygen, issue (to a file and, with the key from the environment,
# to stdout), inspect (valid; another key, another scene: exit 1), revoke by token file and by
# id then inspect (exit 1), and the refusals: key files replaced only with --force, a signing
# key others may read, a damaged token, usage errors (exit 2).
#   tests/token_tool.sh PROBECAST-TOKEN WORK-DIR      (CTest: token_tool_end_to_end)
set -uo pipefail
tool=$1
dir=$2
rm -rf "$dir" && mkdir -p "$dir" && cd "$dir" || exit 1

failures=0
fail() {
  echo "token_tool: FAIL: $*" >&2
  failures=$((failures + 1))
}
# run WANT-RC CMD...: runs CMD with stdout in out.txt, stderr in err.txt; checks its exit code.
run() {
  local want=$1 rc=0
  shift
  "$@" >out.txt 2>err.txt || rc=$?
  if [[ $rc != "$want" ]]; then
    fail "'$*' exited $rc, expected $want"
    sed 's/^/  | /' out.txt err.txt >&2
  fi
}
# has FILE TEXT: FILE contains TEXT.
has() { grep -qF -- "$2" "$1" || { fail "$1 lacks '$2'"; sed 's/^/  | /' "$1" >&2; }; }

run 0 "$tool" keygen --signing-key signing.key --verify-key verify.key
[[ $(stat -c %a signing.key) == 600 ]] || fail "signing.key has mode $(stat -c %a signing.key)"
has signing.key "probecast-signing-key v1 "
has verify.key "probecast-verify-key v1 "
run 1 "$tool" keygen --signing-key signing.key --verify-key verify.key
has err.txt "signing.key exists (--force to replace it)"
run 0 "$tool" keygen --signing-key other.key --verify-key other.pub
run 0 "$tool" keygen --signing-key other.key --verify-key other.pub --force

run 0 "$tool" issue --signing-key signing.key --client alice --scene sponza --role editor \
  --weight 3 --ttl 2h --output alice.token
[[ $(stat -c %a alice.token) == 600 ]] || fail "alice.token has mode $(stat -c %a alice.token)"
grep -qE '^pct1\.[A-Za-z0-9_-]+\.[A-Za-z0-9_-]{86}$' alice.token || fail "alice.token: $(cat alice.token)"

run 0 "$tool" inspect alice.token --verify-key verify.key --scene sponza
has out.txt "client   alice"
has out.txt "scene    sponza"
has out.txt "role     editor"
has out.txt "weight   3"
has out.txt "status   valid"
id=$(sed -n 's/^id *//p' out.txt)
[[ $id =~ ^[0-9a-f]{32}$ ]] || fail "id '$id'"
# Issued now, for two hours.
issued=$(sed -n 's/^issued .*(\([0-9]*\))$/\1/p' out.txt)
expires=$(sed -n 's/^expires .*(\([0-9]*\))$/\1/p' out.txt)
(( expires - issued == 7200 )) || fail "issued $issued, expires $expires"
(( issued - $(date +%s) < 5 && $(date +%s) - issued < 60 )) || fail "issued at $issued"

run 1 "$tool" inspect alice.token --verify-key other.pub
has out.txt "status   invalid: bad_signature"
has err.txt "signed by none of the 1 verify key(s)"
# Keys in rotation: either one verifies.
run 0 "$tool" inspect alice.token --verify-key other.pub --verify-key verify.key
run 1 "$tool" inspect alice.token --verify-key verify.key --scene cornell
has out.txt "status   invalid: wrong_scene"
# Without a key the claims are shown, unverified.
run 0 "$tool" inspect alice.token
has out.txt "status   not verified"

# The key from the environment, the token on stdout.
PROBECAST_SIGNING_KEY=$(cat signing.key) run 0 "$tool" issue --client bob
head -c 5 out.txt | grep -q '^pct1\.' || fail "issue printed: $(cat out.txt)"
cp out.txt bob.token
run 0 "$tool" inspect bob.token --verify-key verify.key --scene anything
has out.txt "scene    *"
has out.txt "role     viewer"
has out.txt "weight   1"
bob=$(sed -n 's/^id *//p' out.txt)

run 0 "$tool" revoke --list revoked.txt alice.token
has revoked.txt "$id  # client alice, revoked "
run 1 "$tool" inspect alice.token --verify-key verify.key --list revoked.txt
has out.txt "status   invalid: revoked"
run 0 "$tool" revoke --list revoked.txt alice.token
has out.txt "already revoked"
run 0 "$tool" inspect bob.token --verify-key verify.key --list revoked.txt
run 0 "$tool" revoke --list revoked.txt "$bob"
run 1 "$tool" inspect bob.token --verify-key verify.key --list revoked.txt
has out.txt "status   invalid: revoked"
[[ $(grep -c . revoked.txt) == 2 ]] || fail "revoked.txt: $(cat revoked.txt)"
run 1 "$tool" revoke --list revoked.txt not-a-token
has err.txt "neither a token id"

# A damaged token: one character of its id changed (still well formed, no longer signed).
c=$(cut -c 11 alice.token)
[[ $c == A ]] && r=B || r=A
sed "s/^\(.\{10\}\)./\1$r/" alice.token > damaged.token
run 1 "$tool" inspect damaged.token --verify-key verify.key
has out.txt "status   invalid: bad_signature"
printf 'pct1.garbage\n' > garbage.token
run 1 "$tool" inspect garbage.token
has err.txt "garbage.token: token has no signature part"

# A signing key others may read is refused, as ssh refuses such a key.
chmod 644 signing.key
run 1 "$tool" issue --signing-key signing.key --client carol
has err.txt "accessible by group or others (mode 0644): chmod 600 it"
chmod 600 signing.key
run 1 "$tool" issue --signing-key signing.key --client "$(printf 'tab\there')"
has err.txt "non-printable"

# Usage errors.
run 2 "$tool"
run 2 "$tool" issue --signing-key signing.key
run 2 "$tool" issue --signing-key signing.key --client x --ttl 5x
has err.txt "expected a duration"
run 2 "$tool" issue --signing-key signing.key --client x --ttl 0s
run 2 "$tool" issue --signing-key signing.key --client x --role admin
run 2 "$tool" issue --signing-key signing.key --client x --weight 17
run 2 "$tool" revoke alice.token
run 0 "$tool" issue --help
has out.txt "--ttl TEXT:DURATION=24h"
has out.txt "--scene TEXT=*"

if ((failures > 0)); then
  echo "token_tool: $failures check(s) failed" >&2
  exit 1
fi
echo "token_tool: keygen, issue, inspect, revoke and their refusals as expected"
