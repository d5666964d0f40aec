#!/usr/bin/env bash
# System packages the test suite needs, installed only when missing (idempotent, quiet).
# redis-server: the service tests run the Redis queue against a real server.
# chromium: the browser tests drive Debian's Chromium (Playwright's own browser download
# needs hosts we cannot reach, and is never used).
set -euo pipefail

missing=()
command -v redis-server >/dev/null 2>&1 || missing+=(redis-server)
[ -x /usr/bin/chromium ] || missing+=(chromium)

if [ ${#missing[@]} -eq 0 ]; then
    exit 0
fi
if [ "$(id -u)" -ne 0 ] || ! command -v apt-get >/dev/null 2>&1; then
    echo "note: ${missing[*]} missing and cannot be installed here (needs root and apt-get);" \
         "the tests that need it will be skipped" >&2
    exit 0
fi
echo "installing system packages: ${missing[*]}" >&2
export DEBIAN_FRONTEND=noninteractive
apt-get update -qq >/dev/null
apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
# the Debian package starts a system-wide server; the tests start their own on a free port
if command -v service >/dev/null 2>&1; then service redis-server stop >/dev/null 2>&1 || true; fi
