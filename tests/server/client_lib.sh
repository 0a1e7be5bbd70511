# Shared by the CLI-against-obscurad scripts (client.sh, client_paging.sh), sourced after they set
# cli and daemon: the pass/fail counters with check, and how much slower the sanitizer build is.
pass=0 fail=0
check() { # description, command...
  local d=$1
  shift
  if "$@"; then pass=$((pass + 1)); echo "ok: $d"; else fail=$((fail + 1)); echo "FAIL: $d"; fi
}
# The sanitizer build is many times slower.
slow=1
case "$cli$daemon" in *asan* | *sanitize*) slow=4 ;; esac
