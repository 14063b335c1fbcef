#!/usr/bin/env bash
# CTest fixture: a throw-away PostgreSQL server for the store's PostgreSQL
# tests. `start FOLDER` runs Debian's initdb in a new folder under /tmp
# (named in FOLDER/datadir: the server's user must be able to reach it),
# starts the server on a free port of 127.0.0.1, creates the
# database "xgauge" and writes its URL to FOLDER/url. Where that cannot be
# done (no PostgreSQL binaries, running as root without the postgres user,
# a server that does not start), it writes the reason to FOLDER/skip
# instead and still succeeds, so the tests that use the fixture report
# themselves as skipped with that reason, never as passed. `stop FOLDER`
# stops the server and removes the folder.
set -u
action=$1 folder=$2
bin=""
for d in /usr/lib/postgresql/*/bin; do [ -x "$d/initdb" ] && bin=$d; done

as_owner() {
  # initdb and postgres refuse to run as root: run them as "postgres".
  if [ "$(id -u)" -eq 0 ]; then runuser -u postgres -- "$@"; else "$@"; fi
}

skip() {
  echo "$1" > "$folder/skip"
  echo "postgres fixture: $1" >&2
  exit 0
}

case "$action" in
  start)
    rm -rf "$folder"
    mkdir -p "$folder"
    [ -n "$bin" ] || skip "no PostgreSQL server binaries (/usr/lib/postgresql/*/bin/initdb): install postgresql"
    data=$(mktemp -d /tmp/xgauge_pg.XXXXXX) || skip "cannot make a folder in /tmp"
    echo "$data" > "$folder/datadir"
    if [ "$(id -u)" -eq 0 ]; then
      id postgres > /dev/null 2>&1 || skip "running as root and there is no 'postgres' user to run the server as"
      chown postgres "$data"
    fi
    as_owner "$bin/initdb" -D "$data/db" -A trust -U xgauge --no-sync > "$folder/initdb.log" 2>&1 \
      || skip "initdb failed: $(tail -n 3 "$folder/initdb.log" | tr '\n' ' ')"
    port=$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
    as_owner "$bin/pg_ctl" -D "$data/db" -l "$data/server.log" -w -t 60 \
      -o "-p $port -k $data -c listen_addresses=127.0.0.1 -c fsync=off" start > /dev/null 2>&1 \
      || skip "the server did not start: $(tail -n 3 "$data/server.log" 2>/dev/null | tr '\n' ' ')"
    as_owner "$bin/createdb" -h 127.0.0.1 -p "$port" -U xgauge xgauge > "$folder/createdb.log" 2>&1 \
      || skip "createdb failed: $(cat "$folder/createdb.log" | tr '\n' ' ')"
    echo "postgresql://xgauge@127.0.0.1:$port/xgauge" > "$folder/url"
    ;;
  stop)
    data=$(cat "$folder/datadir" 2>/dev/null)
    if [ -n "$bin" ] && [ -n "$data" ] && [ -f "$data/db/postmaster.pid" ]; then
      as_owner "$bin/pg_ctl" -D "$data/db" -m immediate stop > /dev/null 2>&1
    fi
    [ -n "$data" ] && rm -rf "$data"
    rm -rf "$folder"
    ;;
  *)
    echo "usage: $0 start|stop FOLDER" >&2
    exit 2
    ;;
esac
