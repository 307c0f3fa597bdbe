import { defineConfig } from 'vite';

// The bundle is committed (web/dist) and embedded into the binary, so the server needs no Node.
// `base: '/'`: the service serves index.html at / and the assets under /assets/.
export default defineConfig({
  base: '/',
  server: {
    // `npm run dev` proxies the API to a local `landform serve`.
    proxy: Object.fromEntries(
      ['/v1', '/openapi.json', '/healthz'].map((p) => [p, 'http://127.0.0.1:8080']),
    ),
    fs: { allow: ['..'] },
  },
  build: {
    outDir: 'dist',
    emptyOutDir: true,
    target: 'es2022',
    chunkSizeWarningLimit: 1024,
    reportCompressedSize: true,
  },
});
