#!/bin/sh
# A throwaway PostgreSQL for the store's tests: `pg.sh start DIR PORT` creates a cluster in DIR
# (initdb), starts it on 127.0.0.1:PORT only, with trust authentication and fsync off (its data
# is thrown away), creates the database "obscura" and prints its URL; `pg.sh stop DIR` stops it
# and removes DIR. PostgreSQL refuses to run as root, so as root both run as the postgres user.
set -eu
BIN=${OBSCURA_PG_BIN:-/usr/lib/postgresql/15/bin}

as_owner() {
  if [ "$(id -u)" = 0 ]; then
    su postgres -s /bin/sh -c "$1"
  else
    sh -c "$1"
  fi
}

case "${1:-}" in
  start)
    dir=$2
    port=$3
    [ -x "$BIN/initdb" ] || { echo "pg.sh: no $BIN/initdb (install postgresql-15)" >&2; exit 1; }
    if [ -f "$dir/data/postmaster.pid" ]; then "$0" stop "$dir"; fi
    rm -rf "$dir"
    mkdir -p "$dir"
    [ "$(id -u)" = 0 ] && chown postgres "$dir"
    as_owner "'$BIN/initdb' -D '$dir/data' -U postgres -A trust -E UTF8 --no-locale >'$dir/initdb.log' 2>&1" ||
      { cat "$dir/initdb.log" >&2; exit 1; }
    # Sockets in DIR, not /var/run/postgresql (which may be missing or another cluster's).
    opts="-c listen_addresses=127.0.0.1 -c port=$port -c unix_socket_directories='$dir'"
    opts="$opts -c fsync=off -c synchronous_commit=off -c full_page_writes=off -c max_connections=200"
    as_owner "'$BIN/pg_ctl' -D '$dir/data' -l '$dir/server.log' -w -t 60 -o \"$opts\" start >/dev/null" ||
      { cat "$dir/server.log" >&2; exit 1; }
    as_owner "'$BIN/psql' -h 127.0.0.1 -p $port -U postgres -d postgres -q -c 'CREATE DATABASE obscura'" >/dev/null
    echo "postgresql://postgres@127.0.0.1:$port/obscura"
    ;;
  stop)
    dir=$2
    if [ -f "$dir/data/postmaster.pid" ]; then
      as_owner "'$BIN/pg_ctl' -D '$dir/data' -m immediate -w stop >/dev/null" || true
    fi
    rm -rf "$dir"
    ;;
  *)
    echo "usage: pg.sh start DIR PORT | pg.sh stop DIR" >&2
    exit 2
    ;;
esac
