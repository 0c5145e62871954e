#!/usr/bin/env bash
# The README's test command: installs what the tests need and runs every check.
# Chromium (Debian's package) drives the viewer's tests in a headless browser; without it (no
# apt, no root) those tests are skipped, with their reason.
set -euo pipefail
cd "$(dirname "$0")/.."
if ! command -v chromium >/dev/null; then
    (apt-get update -qq && apt-get install -y -qq --no-install-recommends chromium >/dev/null) ||
        echo "chromium could not be installed: the browser tests of the viewer will be skipped"
fi
pip install -e ".[test]"
bash tools/check.sh
