// model_upload.js: the picked files as one upload — one file as it is, a model with its side
// files as a stored zip whose records another reader (read back here by its own offsets) accepts.

import { test } from 'node:test';
import { crc32, planUpload, storedZip, uploadBody } from '../../../client_web/js/model_upload.js';
import { assert, same } from './same.mjs';

const FORMATS = ['obj', 'ply', 'stl', 'glb', 'gltf', 'zip'];
const file = (name, text) => new File([new TextEncoder().encode(text)], name);

// The entries of a zip, read from its end record and central directory (names, sizes, CRCs, data).
function readZip(bytes) {
  const v = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  const end = bytes.length - 22;
  assert.equal(v.getUint32(end, true), 0x06054b50);
  const n = v.getUint16(end + 10, true);
  let at = v.getUint32(end + 16, true);
  assert.equal(at + v.getUint32(end + 12, true), end);
  const out = [];
  for (let i = 0; i < n; i++) {
    assert.equal(v.getUint32(at, true), 0x02014b50);
    const size = v.getUint32(at + 24, true);
    const nameLen = v.getUint16(at + 28, true);
    const local = v.getUint32(at + 42, true);
    const name = new TextDecoder().decode(bytes.subarray(at + 46, at + 46 + nameLen));
    assert.equal(v.getUint32(local, true), 0x04034b50);
    assert.equal(v.getUint16(local + 8, true), 0);   // stored
    const data = bytes.subarray(local + 30 + v.getUint16(local + 26, true), local + 30 + v.getUint16(local + 26, true) + size);
    assert.equal(crc32(data), v.getUint32(at + 16, true));
    out.push({ name, text: new TextDecoder().decode(data) });
    at += 46 + nameLen;
  }
  return out;
}

test('crc32 is zlib\'s', () => {
  same([crc32(new TextEncoder().encode('123456789')), crc32(new Uint8Array(0))], [0xcbf43926, 0]);
});

test('a stored zip reads back entry by entry, UTF-8 names included', () => {
  const enc = new TextEncoder();
  const zip = storedZip([{ name: 'box.gltf', bytes: enc.encode('{"asset":{}}') }, { name: 'tëxture.png', bytes: enc.encode('PNG') }]);
  same(readZip(zip), [{ name: 'box.gltf', text: '{"asset":{}}' }, { name: 'tëxture.png', text: 'PNG' }]);
});

test('one file is sent as it is; a model with its side files as a zip of them all', async () => {
  const one = planUpload([file('ball.obj', 'v 0 0 0')], FORMATS);
  same([one.format, one.side.length, await uploadBody(one) === one.main], ['obj', 0, true]);
  const picked = [file('box.bin', 'BIN'), file('box.gltf', '{}'), file('logo.png', 'PNG')];
  const plan = planUpload(picked, FORMATS);
  same([plan.format, plan.main.name, plan.side.map((f) => f.name)], ['zip', 'box.gltf', ['box.bin', 'logo.png']]);
  const body = await uploadBody(plan);
  const bytes = new Uint8Array(await body.arrayBuffer());
  same([body.name, bytes.length, readZip(bytes).map((e) => e.name)], ['box.zip', plan.size, ['box.gltf', 'box.bin', 'logo.png']]);
});

test('several models, none, or a zip with other files are refused before anything is sent', () => {
  for (const picked of [[file('a.obj', ''), file('b.stl', '')], [file('a.bin', ''), file('a.png', '')], [file('m.zip', ''), file('a.png', '')]]) {
    const plan = planUpload(picked, FORMATS);
    assert.ok(plan.problem && plan.problem.includes('pick one model file'), JSON.stringify(plan));
  }
});
