// Reads a KTX2 file with ktx-parse (an independent, pure-JS parser) and prints
// what it found as JSON: the header fields, the data format descriptor's colour
// model, primaries, transfer and samples, the key/value data, and per level
// its byte length and the first texel's four half floats.
import { readFileSync } from "node:fs";
import { read } from "ktx-parse";

function half(bits) {
  const s = bits & 0x8000 ? -1 : 1;
  const e = (bits >> 10) & 0x1f;
  const m = bits & 0x3ff;
  if (e === 0) return s * m * 2 ** -24;
  if (e === 31) return m ? NaN : s * Infinity;
  return s * (1 + m / 1024) * 2 ** (e - 15);
}

const bytes = new Uint8Array(readFileSync(process.argv[2]));
const c = read(bytes);
const dfd = c.dataFormatDescriptor[0];
const out = {
  vkFormat: c.vkFormat,
  typeSize: c.typeSize,
  pixelWidth: c.pixelWidth,
  pixelHeight: c.pixelHeight,
  pixelDepth: c.pixelDepth,
  layerCount: c.layerCount,
  faceCount: c.faceCount,
  levelCount: c.levelCount,
  supercompressionScheme: c.supercompressionScheme,
  dfd: {
    colorModel: dfd.colorModel,
    colorPrimaries: dfd.colorPrimaries,
    transferFunction: dfd.transferFunction,
    versionNumber: dfd.versionNumber,
    bytesPlane0: dfd.bytesPlane[0],
    samples: dfd.samples.map((s) => ({
      bitOffset: s.bitOffset,
      bitLength: s.bitLength,
      channelType: s.channelType,
      sampleLower: s.sampleLower,
      sampleUpper: s.sampleUpper,
    })),
  },
  keyValue: Object.fromEntries(
    Object.entries(c.keyValue).map(([k, v]) => [k, typeof v === "string" ? v : Array.from(v)]),
  ),
  levels: c.levels.map((l) => {
    const d = new DataView(l.levelData.buffer, l.levelData.byteOffset, l.levelData.byteLength);
    return {
      byteLength: l.levelData.byteLength,
      uncompressedByteLength: l.uncompressedByteLength,
      firstTexel: [0, 2, 4, 6].map((o) => half(d.getUint16(o, true))),
    };
  }),
};
console.log(JSON.stringify(out));
