#!/bin/bash
# The README's image: `tolerax demo`'s own figure, made from the current code.
#   bash docs/make_images.sh
set -euo pipefail
cd "$(dirname "$0")/.."
out=$(mktemp -d)
tolerax demo --out "$out"
cp "$out/demo.png" docs/demo.png
echo "docs/demo.png from tolerax demo ($(git rev-parse --short HEAD))"
