#!/usr/bin/env bash
# Installs qemu-system-arm >= 9 (needed for `-M b-l475e-iot01a`) when it is missing.
# Debian bookworm's own QEMU (7.2) lacks the board; bookworm-backports has 10.x.
set -euo pipefail
have_board() {
  command -v qemu-system-arm >/dev/null 2>&1 &&
    qemu-system-arm -M help 2>/dev/null | grep -q '^b-l475e-iot01a'
}
if have_board; then
  echo "setup-qemu: $(qemu-system-arm --version | head -n1) with b-l475e-iot01a is present"
  exit 0
fi
if [ "$(id -u)" != 0 ] || ! command -v apt-get >/dev/null 2>&1; then
  echo "setup-qemu: qemu-system-arm with the b-l475e-iot01a machine is missing; install it with:" >&2
  echo "  (Debian bookworm, as root) add 'bookworm-backports' to the Suites of /etc/apt/sources.list.d/debian.sources," >&2
  echo "  then: apt-get update && apt-get install -y --no-install-recommends -t bookworm-backports qemu-system-arm" >&2
  exit 1
fi
src=/etc/apt/sources.list.d/debian.sources
if [ -f "$src" ] && ! grep -q 'bookworm-backports' "$src"; then
  echo "setup-qemu: adding bookworm-backports to $src"
  # Same URIs and Signed-By as the main bookworm entry.
  sed -i '0,/^Suites: bookworm bookworm-updates$/s//Suites: bookworm bookworm-updates bookworm-backports/' "$src"
  if ! grep -q 'bookworm-backports' "$src"; then
    printf '\nTypes: deb\nURIs: http://deb.debian.org/debian\nSuites: bookworm-backports\nComponents: main\nSigned-By: /usr/share/keyrings/debian-archive-keyring.gpg\n' >> "$src"
  fi
fi
echo "setup-qemu: apt-get update && apt-get install -t bookworm-backports qemu-system-arm"
apt-get update -qq
DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends -t bookworm-backports qemu-system-arm >/dev/null
have_board || { echo "setup-qemu: installed QEMU still has no b-l475e-iot01a machine" >&2; exit 1; }
echo "setup-qemu: $(qemu-system-arm --version | head -n1) installed"
