// The raw samples of an 8-bit RGBA PNG (the server's splat maps), decoded here because a canvas
// keeps colours premultiplied by alpha: where alpha is 0 it loses the other three channels,
// which in a splat map are weights, not colours.

/** Width, height and RGBA bytes, or null for any other PNG (not 8-bit RGBA, interlaced). */
export async function decodeRgbaPng(bytes: ArrayBuffer): Promise<{ width: number; height: number; data: Uint8Array } | null> {
  const b = new Uint8Array(bytes);
  const view = new DataView(bytes);
  const signature = [137, 80, 78, 71, 13, 10, 26, 10];
  if (b.length < 33 || signature.some((v, k) => b[k] !== v)) return null;
  const width = view.getUint32(16);
  const height = view.getUint32(20);
  // bit depth 8, colour type 6 (RGBA), no interlace
  if (b[24] !== 8 || b[25] !== 6 || b[28] !== 0 || width * height > 1 << 26) return null;
  const parts: Uint8Array[] = [];
  for (let at = 8; at + 8 <= b.length; ) {
    const length = view.getUint32(at);
    const type = String.fromCharCode(...b.subarray(at + 4, at + 8));
    if (type === 'IDAT') parts.push(b.subarray(at + 8, at + 8 + length));
    if (type === 'IEND') break;
    at += 12 + length;
  }
  // IDAT is a zlib stream: the 'deflate' format of DecompressionStream.
  const inflated = new Uint8Array(await new Response(new Blob(parts as BlobPart[]).stream().pipeThrough(new DecompressionStream('deflate'))).arrayBuffer());
  const stride = width * 4;
  if (inflated.length < (stride + 1) * height) return null;
  const out = new Uint8Array(stride * height);
  for (let y = 0; y < height; y++) {
    const filter = inflated[y * (stride + 1)];
    const row = inflated.subarray(y * (stride + 1) + 1, (y + 1) * (stride + 1));
    const at = y * stride;
    for (let x = 0; x < stride; x++) {
      const left = x >= 4 ? out[at + x - 4] : 0;
      const up = y > 0 ? out[at - stride + x] : 0;
      const corner = x >= 4 && y > 0 ? out[at - stride + x - 4] : 0;
      let v = row[x];
      if (filter === 1) v += left;
      else if (filter === 2) v += up;
      else if (filter === 3) v += (left + up) >> 1;
      else if (filter === 4) v += paeth(left, up, corner);
      out[at + x] = v & 255;
    }
  }
  return { width, height, data: out };
}

function paeth(a: number, b: number, c: number): number {
  const p = a + b - c;
  const pa = Math.abs(p - a);
  const pb = Math.abs(p - b);
  const pc = Math.abs(p - c);
  return pa <= pb && pa <= pc ? a : pb <= pc ? b : c;
}
