// What the editor and the viewer take from three.js: one ES module, bundled by esbuild
// (`make web`) into src/facadeforge/editor/static/vendor/three.bundle.js so that the pages work
// offline, with nothing fetched from a CDN.
export * as THREE from 'three';
export { OrbitControls } from 'three/examples/jsm/controls/OrbitControls.js';
export { GLTFLoader } from 'three/examples/jsm/loaders/GLTFLoader.js';
export { OBJLoader } from 'three/examples/jsm/loaders/OBJLoader.js';
export { MTLLoader } from 'three/examples/jsm/loaders/MTLLoader.js';
export { PLYLoader } from 'three/examples/jsm/loaders/PLYLoader.js';
