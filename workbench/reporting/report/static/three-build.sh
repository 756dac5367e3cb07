#!/usr/bin/env bash
# Rebuild three.min.js, the part of three.js the report's rig panel uses, as one classic script (a page opened from
# file:// may not load ES modules): esbuild bundles and minifies the npm packages below into an IIFE whose global is
# THREE. Run from anywhere; needs node and npm. The licence beside it is three.js's own (MIT).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
build=$(mktemp -d)
trap 'rm -rf "$build"' EXIT
cd "$build"
npm init -y >/dev/null
npm install --silent --no-audit --no-fund three@0.187.0 esbuild@0.28.2
cat > entry.js <<'JS'
export {
  WebGLRenderer, Scene, PerspectiveCamera, DirectionalLight, HemisphereLight, Color, Box3, Vector3,
  MeshStandardMaterial, BufferAttribute, BufferGeometry, Mesh, DoubleSide,
} from "three";
export { GLTFLoader } from "three/examples/jsm/loaders/GLTFLoader.js";
export { OrbitControls } from "three/examples/jsm/controls/OrbitControls.js";
JS
npx esbuild entry.js --bundle --minify --format=iife --global-name=THREE --legal-comments=none \
    --banner:js="/* three.js r187 (https://threejs.org), MIT licence: three-LICENSE.txt. Built by three-build.sh. */" \
    --outfile="$here/three.min.js"
cp node_modules/three/LICENSE "$here/three-LICENSE.txt"
