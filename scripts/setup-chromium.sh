#!/usr/bin/env bash
# Installs Debian's chromium and poppler-utils when missing: the certificate tests print
# `accelcal report`'s HTML page to PDF with `chromium --headless --print-to-pdf` and read each
# printed page back with `pdftotext` (its page numbers, its identification, its sections).
set -euo pipefail
missing=()
command -v chromium >/dev/null 2>&1 || missing+=(chromium)
command -v pdftotext >/dev/null 2>&1 || missing+=(poppler-utils)
if [ ${#missing[@]} -eq 0 ]; then
  echo "setup-chromium: $(chromium --version 2>/dev/null | head -n1) and pdftotext are present"
  exit 0
fi
if [ "$(id -u)" != 0 ] || ! command -v apt-get >/dev/null 2>&1; then
  echo "setup-chromium: ${missing[*]} missing; install with (Debian, as root):" >&2
  echo "  apt-get update && apt-get install -y --no-install-recommends ${missing[*]}" >&2
  exit 1
fi
echo "setup-chromium: apt-get update && apt-get install ${missing[*]}"
apt-get update -qq
DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
