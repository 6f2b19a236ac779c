// session.js: a session's scene, the bodies that ask for a scene again, the render settings kept.

import './declared.mjs';
import { test } from 'node:test';
import { changed, pickRender, sceneBody, sceneBodyKeys, sceneOf } from '../../../client_web/js/session.js';
import { same } from './same.mjs';

const before = { scenario: 1, n: 512, seed: 1, radius: 1, motion: 'deformable' };

test('a thesis scenario, the museum and a mesh scene as state.scene', () => {
  same(sceneOf({ scenario: 2, n: 128, n_spheres: 128, seed: 3, radius: 0.5 }, before),
    { scenario: 2, n: 128, seed: 3, radius: 0.5, motion: 'deformable', n_spheres: 128, animated: false, n_triangles: 0, n_meshes: 0, n_shapes: 0 });
  same(sceneOf({ n_spheres: 832, museum: { n: 256, kind: 'rigid', seed: 0 }, animated: true }, before),
    { scenario: 'museum', n: 256, seed: 0, radius: 1, motion: 'rigid', n_spheres: 832, animated: true, n_triangles: 0, n_meshes: 0, n_shapes: 0 });
  same(sceneOf({ n_spheres: 3, mesh_scene: { kind: 'teapot' }, n_triangles: 6320, n_meshes: 1 }, before).scenario, 'mesh:teapot');
  same(sceneOf({ scenario: 2, n: 64, n_spheres: 64, sky: true }, before).scenario, 'sky:2');
  const table = sceneOf({ n_spheres: 0, mesh_scene: { kind: 'table' }, n_shapes: 14 }, before);
  same([table.scenario, table.n_shapes, sceneBody(table)], ['mesh:table', 14, { mesh_scene: { kind: 'table' } }]);
});

test('a scenario under the sky asks for its recipe with sky: true', () => {
  same(sceneBody({ ...before, scenario: 'sky:2' }), { scenario: 2, n: 512, seed: 1, radius: 1, sky: true });
});

test('the POST /api/sessions body of each kind of scene', () => {
  same([sceneBody(before), sceneBody({ scenario: 'museum', n: 64 }), sceneBody({ scenario: 'mesh:room', n: 3 })],
    [{ scenario: 1, n: 512, seed: 1, radius: 1 }, { museum: { n: 64, kind: 'deformable', seed: 0 } }, { mesh_scene: { kind: 'room' } }]);
  same([sceneBodyKeys(before), sceneBodyKeys({ ...before, scenario: 'museum' })],
    [{ scenario: 1, n: 512, seed: 1, radius: 1 }, { scenario: 'museum', n: 512, seed: 1, radius: 1, motion: 'deformable' }]);
});

test('the render settings kept, and what differs', () => {
  // the settings the service declares for the client, in its order; the version and camera are not settings
  same(pickRender({ method: 'bih', width: 8, version: 3, format: 'png', camera: {} }), { width: 8, method: 'bih', format: 'png' });
  same([changed({ width: 8, height: 9 }, { width: 8, height: 10 }), changed({ width: 8 }, null)], [{ height: 9 }, { width: 8 }]);
});
