#!/usr/bin/env bash
# Installs Debian's libxml2-utils when missing: the DCC tests validate every DCC that
# `accelcal certificate --dcc` writes with `xmllint --noout --nonet --schema` against the PTB
# schema set shipped in tests/data/dcc/ (resolved offline through its catalog.xml).
set -euo pipefail
if command -v xmllint >/dev/null 2>&1; then
  echo "setup-xmllint: $(xmllint --version 2>&1 | head -n1) is present"
  exit 0
fi
if [ "$(id -u)" != 0 ] || ! command -v apt-get >/dev/null 2>&1; then
  echo "setup-xmllint: xmllint missing; install with (Debian, as root):" >&2
  echo "  apt-get update && apt-get install -y --no-install-recommends libxml2-utils" >&2
  exit 1
fi
echo "setup-xmllint: apt-get update && apt-get install libxml2-utils"
apt-get update -qq
DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends libxml2-utils >/dev/null
