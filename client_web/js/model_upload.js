// The model files picked in the settings sheet, as one upload (POST /api/sessions/{id}/meshes):
// one file as it is (.obj .ply .stl .glb .gltf, or a .zip of the model's folder); a model file
// picked together with its side files (a .gltf with its .bin and images, an .obj with its .mtl)
// as a zip built here, which the service opens as format=zip. The zip stores the files as they
// are (method 0): no compression library in the page, and the service bounds a zip by the sizes
// its entries declare.

const CRC_TABLE = (() => {
  const t = new Uint32Array(256);
  for (let n = 0; n < 256; n++) {
    let c = n;
    for (let k = 0; k < 8; k++) c = c & 1 ? 0xedb88320 ^ (c >>> 1) : c >>> 1;
    t[n] = c >>> 0;
  }
  return t;
})();

// The CRC-32 zip records of each entry (IEEE 802.3, as zlib's crc32).
export function crc32(bytes) {
  let c = 0xffffffff;
  for (let i = 0; i < bytes.length; i++) c = CRC_TABLE[(c ^ bytes[i]) & 0xff] ^ (c >>> 8);
  return (c ^ 0xffffffff) >>> 0;
}

// A zip of `entries` ([{name, bytes: Uint8Array}]) stored uncompressed: local headers and data,
// the central directory, its end record. Names are UTF-8 (flag bit 11).
export function storedZip(entries) {
  const enc = new TextEncoder();
  const items = entries.map((e) => ({ name: enc.encode(e.name), bytes: e.bytes, crc: crc32(e.bytes) }));
  const localSize = items.reduce((s, e) => s + 30 + e.name.length + e.bytes.length, 0);
  const centralSize = items.reduce((s, e) => s + 46 + e.name.length, 0);
  const out = new Uint8Array(localSize + centralSize + 22);
  const view = new DataView(out.buffer);
  let at = 0;
  const offsets = [];
  for (const e of items) {
    offsets.push(at);
    view.setUint32(at, 0x04034b50, true);
    view.setUint16(at + 4, 20, true);            // version needed: 2.0
    view.setUint16(at + 6, 0x0800, true);        // UTF-8 names
    view.setUint16(at + 8, 0, true);             // stored
    view.setUint32(at + 14, e.crc, true);
    view.setUint32(at + 18, e.bytes.length, true);
    view.setUint32(at + 22, e.bytes.length, true);
    view.setUint16(at + 26, e.name.length, true);
    out.set(e.name, at + 30);
    out.set(e.bytes, at + 30 + e.name.length);
    at += 30 + e.name.length + e.bytes.length;
  }
  const central = at;
  items.forEach((e, i) => {
    view.setUint32(at, 0x02014b50, true);
    view.setUint16(at + 4, 20, true);            // made by: 2.0, MS-DOS attributes (no links)
    view.setUint16(at + 6, 20, true);
    view.setUint16(at + 8, 0x0800, true);
    view.setUint16(at + 10, 0, true);
    view.setUint32(at + 16, e.crc, true);
    view.setUint32(at + 20, e.bytes.length, true);
    view.setUint32(at + 24, e.bytes.length, true);
    view.setUint16(at + 28, e.name.length, true);
    view.setUint32(at + 42, offsets[i], true);
    out.set(e.name, at + 46);
    at += 46 + e.name.length;
  });
  view.setUint32(at, 0x06054b50, true);
  view.setUint16(at + 8, items.length, true);
  view.setUint16(at + 10, items.length, true);
  view.setUint32(at + 12, at - central, true);
  view.setUint32(at + 16, central, true);
  return out;
}

export const suffixOf = (name) => (/\.([^.]+)$/.exec(String(name)) || [])[1]?.toLowerCase() || '';

// What the picked files make (`formats`: the model formats, 'zip' among them): {main, side, format,
// size} — the model file, the files sent beside it, the upload's format and its bytes (a zip's
// headers counted) — or {problem} in the panel's words, when they make no one model.
export function planUpload(files, formats) {
  const list = Array.from(files || []);
  if (list.length <= 1) {
    const main = list[0];
    return main ? { main, side: [], format: suffixOf(main.name), size: main.size } : { problem: 'no file picked' };
  }
  const models = list.filter((f) => formats.includes(suffixOf(f.name)));
  if (models.length !== 1 || suffixOf(models[0].name) === 'zip') {
    return { problem: `${list.length} files picked, ${models.length} of them models: pick one model file with its side files (.bin, .mtl, images), or one .zip` };
  }
  const main = models[0];
  const side = list.filter((f) => f !== main);
  const enc = new TextEncoder();
  const size = list.reduce((s, f) => s + f.size + 76 + 2 * enc.encode(f.name).length, 22);
  return { main, side, format: 'zip', size };
}

// The body to send for a plan: the file itself, or the zip of the model file and its side files
// (each by its own name: the browser gives no folders).
export async function uploadBody(plan) {
  if (!plan.side.length) return plan.main;
  const entries = [];
  for (const f of [plan.main, ...plan.side]) entries.push({ name: f.name, bytes: new Uint8Array(await f.arrayBuffer()) });
  const base = plan.main.name.replace(/\.[^.]+$/, '') || 'model';
  return new File([storedZip(entries)], `${base}.zip`, { type: 'application/zip' });
}
