#!/usr/bin/env bash
# Installs Debian's PostgreSQL server when it is missing: the database tests (tests/db_pg.rs)
# start a throwaway cluster of their own with scripts/postgres-cluster.sh. No cluster is created
# or started by the installation.
set -euo pipefail
have_server() { ls /usr/lib/postgresql/*/bin/initdb >/dev/null 2>&1; }
if have_server; then
  echo "setup-postgres: $(ls -d /usr/lib/postgresql/*/bin/initdb | sort -V | tail -n1) is present"
  exit 0
fi
if [ "$(id -u)" != 0 ] || ! command -v apt-get >/dev/null 2>&1; then
  echo "setup-postgres: the PostgreSQL server is missing; install it with (Debian, as root):" >&2
  echo "  apt-get update && apt-get install -y --no-install-recommends postgresql" >&2
  exit 1
fi
# The package would create and start a 'main' cluster; the tests need none.
mkdir -p /etc/postgresql-common
if [ ! -e /etc/postgresql-common/createcluster.conf ]; then
  echo "create_main_cluster = false" > /etc/postgresql-common/createcluster.conf
fi
echo "setup-postgres: apt-get update && apt-get install postgresql"
apt-get update -qq
DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends postgresql >/dev/null
have_server || { echo "setup-postgres: installed, but no /usr/lib/postgresql/*/bin/initdb" >&2; exit 1; }
echo "setup-postgres: $(ls -d /usr/lib/postgresql/*/bin/initdb | sort -V | tail -n1) installed"
