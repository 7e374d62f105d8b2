#!/usr/bin/env bash
# A throwaway PostgreSQL cluster for the tests, in a directory of its own, reached only through
# a unix socket in that directory (no TCP port, so clusters of parallel tests never collide).
#   postgres-cluster.sh start DIR   initdb + start; prints the connection string
#   postgres-cluster.sh stop DIR    stop at once and remove DIR
#   postgres-cluster.sh resume DIR  start the cluster DIR holds (initdb first when it holds none);
#                                   prints the connection string
#   postgres-cluster.sh halt DIR    stop it and keep its data (`cargo xtask bench fleet`)
# As root (CI), the server runs as the `postgres` user of Debian's package: it refuses root.
set -euo pipefail
cmd=${1:?start|stop|resume|halt}
dir=${2:?DIR}
bindir=$(ls -d /usr/lib/postgresql/*/bin 2>/dev/null | sort -V | tail -n1)
if [ -z "$bindir" ]; then
  echo "postgres-cluster: no PostgreSQL server; run scripts/setup-postgres.sh" >&2
  exit 1
fi
as_owner() {
  if [ "$(id -u)" = 0 ]; then runuser -u postgres -- "$@"; else "$@"; fi
}
server() {
  as_owner "$bindir/pg_ctl" -D "$dir/data" -l "$dir/server.log" -w -t 60 \
    -o "-c listen_addresses='' -k $dir -c fsync=off -c max_connections=40" start >/dev/null ||
    { cat "$dir/server.log" >&2; exit 1; }
}
case "$cmd" in
resume)
  if [ ! -f "$dir/data/PG_VERSION" ]; then
    exec "$0" start "$dir"
  fi
  if [ ! -f "$dir/data/postmaster.pid" ]; then
    server
  fi
  echo "host=$dir user=accelcal dbname=postgres"
  ;;
halt)
  if [ -f "$dir/data/postmaster.pid" ]; then
    as_owner "$bindir/pg_ctl" -D "$dir/data" -m fast -w stop >/dev/null
  fi
  ;;
start)
  mkdir -p "$dir"
  if [ "$(id -u)" = 0 ]; then chown postgres: "$dir"; fi
  as_owner "$bindir/initdb" -D "$dir/data" -U accelcal --auth=trust -E UTF8 --no-sync --no-instructions >"$dir/initdb.log" 2>&1 ||
    { cat "$dir/initdb.log" >&2; exit 1; }
  server
  echo "host=$dir user=accelcal dbname=postgres"
  ;;
stop)
  if [ -f "$dir/data/postmaster.pid" ]; then
    as_owner "$bindir/pg_ctl" -D "$dir/data" -m immediate -w stop >/dev/null 2>&1 || true
  fi
  rm -rf "$dir"
  ;;
*)
  echo "postgres-cluster: unknown command $cmd (start|stop|resume|halt)" >&2
  exit 2
  ;;
esac
