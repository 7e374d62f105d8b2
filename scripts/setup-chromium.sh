#!/usr/bin/env bash
# Installs Debian's chromium when it is missing: the certificate test prints `accelcal report`'s
# HTML page to PDF with `chromium --headless --print-to-pdf` and checks that it is one A4 page.
set -euo pipefail
if command -v chromium >/dev/null 2>&1; then
  echo "setup-chromium: $(chromium --version 2>/dev/null | head -n1) is present"
  exit 0
fi
if [ "$(id -u)" != 0 ] || ! command -v apt-get >/dev/null 2>&1; then
  echo "setup-chromium: chromium is missing; install it with (Debian, as root):" >&2
  echo "  apt-get update && apt-get install -y --no-install-recommends chromium" >&2
  exit 1
fi
echo "setup-chromium: apt-get update && apt-get install chromium"
apt-get update -qq
DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends chromium >/dev/null
