// An independent reader check of rheo_record's MCAP files: Foxglove's @mcap/core reads the file
// (its indexed reader through the summary, or with --expect-truncated its streaming reader, which
// needs no footer), protobufjs decodes every message with the schema embedded in the file (a
// google.protobuf.FileDescriptorSet), and the counts are printed as JSON.
//
//   node tests/record/read_mcap.mjs FILE [--expect-truncated] [--expect REPORT.json]
//                                   [--rheod RECORDING.json] [--web-root clients/web]
//
// --expect compares the counts per topic with write_sample's report (expected_per_topic).
// --rheod RECORDING.json reads a recording rheod made (`rheoctl record stop --json` gives the
// JSON): the counts per topic must be the Recording's message_counts, every channel must carry
// the schema of its rheo.v1 type, /tool and /frames messages must lie at loop_epoch_unix_ns +
// tick x period_ns (the channels' metadata), /tool must hold one sample per tick but the dropped
// ones, and /scene must hold an object's tetrahedral mesh. The
// packages come from clients/web/node_modules (npm ci there): @mcap/core, @mcap/support (its zstd
// and lz4 decompressors are @foxglove/wasm-zstd and @foxglove/wasm-lz4), @mcap/nodejs, protobufjs.
import { open, readFile } from 'node:fs/promises';
import { createRequire } from 'node:module';
import { dirname, join, resolve } from 'node:path';
import { fileURLToPath } from 'node:url';

const here = dirname(fileURLToPath(import.meta.url));

function parseArgs(argv) {
  const out = { file: null, truncated: false, expect: null, rheod: null, webRoot: join(here, '../../clients/web') };
  for (let i = 0; i < argv.length; ++i) {
    const a = argv[i];
    if (a === '--expect-truncated') out.truncated = true;
    else if (a === '--expect') out.expect = resolve(argv[++i]);
    else if (a === '--rheod') out.rheod = resolve(argv[++i]);
    else if (a === '--web-root') out.webRoot = resolve(argv[++i]);
    else if (!a.startsWith('--') && out.file === null) out.file = resolve(a);
    else throw new Error(`unknown argument ${a}`);
  }
  if (out.file === null) throw new Error('usage: read_mcap.mjs FILE [--expect-truncated] [--expect REPORT.json]');
  return out;
}

const args = parseArgs(process.argv.slice(2));
const require = createRequire(join(args.webRoot, 'package.json'));
const { McapIndexedReader, McapStreamReader } = require('@mcap/core');
const { loadDecompressHandlers } = require('@mcap/support');
const { FileHandleReadable } = require('@mcap/nodejs');
const protobuf = require('protobufjs');
const descriptor = require('protobufjs/ext/descriptor');

const failures = [];
function check(ok, what) {
  if (!ok) failures.push(what);
}

// One protobufjs Type per schema, built from the FileDescriptorSet in the file.
const types = new Map();
function typeOf(schema) {
  if (!types.has(schema.id)) {
    check(schema.encoding === 'protobuf', `schema ${schema.id} (${schema.name}) is ${schema.encoding}, not protobuf`);
    const set = descriptor.FileDescriptorSet.decode(schema.data);
    const root = protobuf.Root.fromDescriptor(set);
    types.set(schema.id, root.lookupType(schema.name));
  }
  return types.get(schema.id);
}

const perTopic = {};
let messages = 0;
let lastLogTime = -1n;
// rheod recordings: what the checks after the read need.
const rheod = { toolTicks: [], tets: 0, sceneVertices: 0, badTimes: [] };
const rheodTypes = {
  '/tool': 'rheo.v1.ToolSample', '/frames': 'rheo.v1.Frame', '/scene': 'rheo.v1.SceneEvent',
  '/parameters': 'rheo.v1.ParameterChange', '/commands': 'rheo.v1.CommandEvent', '/loop': 'rheo.v1.LoopSample',
};
function checkRheod(channel, schema, decoded, msg) {
  check(rheodTypes[channel.topic] === schema.name, `${channel.topic} carries ${schema.name}, not ${rheodTypes[channel.topic]}`);
  const meta = channel.metadata instanceof Map ? Object.fromEntries(channel.metadata) : channel.metadata;
  const tick = channel.topic === '/tool' ? decoded.tick : channel.topic === '/frames' ? decoded.stamp?.tick : undefined;
  if (tick !== undefined) {
    const want = BigInt(meta.loop_epoch_unix_ns) + BigInt(tick) * BigInt(meta.period_ns);
    if (want !== msg.logTime && rheod.badTimes.length < 5) rheod.badTimes.push(`${channel.topic} tick ${tick}: log time ${msg.logTime}, want ${want}`);
  }
  if (channel.topic === '/tool') rheod.toolTicks.push(BigInt(decoded.tick));
  if (channel.topic === '/scene' && decoded.mesh) {
    // protobufjs keeps the descriptor's field names (snake_case).
    const mesh = decoded.mesh;
    const vertices = mesh.vertex_count ?? 0;
    const tets = mesh.tetrahedra ?? [];
    rheod.tets += tets.length / 4;
    rheod.sceneVertices += vertices;
    check(vertices > 0, '/scene: an object without vertices');
    check((mesh.rest_positions ?? []).length === 3 * vertices, `/scene: ${(mesh.rest_positions ?? []).length} rest coordinates for ${vertices} vertices`);
    check(tets.length % 4 === 0 && tets.every((v) => v < vertices), '/scene: tetrahedra index past the vertices');
  }
}

function onMessage(channel, schema, msg, ordered) {
  const type = typeOf(schema);
  const decoded = type.toObject(type.decode(msg.data), { longs: String });
  messages += 1;
  perTopic[channel.topic] = (perTopic[channel.topic] ?? 0) + 1;
  if (args.rheod) {
    checkRheod(channel, schema, decoded, msg);
  } else if ('sequence' in type.fields) {
    // The sample's messages carry the record's sequence and log time; a mis-framed payload would not.
    check((decoded.sequence ?? 0) === msg.sequence, `${channel.topic}: decoded sequence ${decoded.sequence} != record ${msg.sequence}`);
  }
  if (!args.rheod && decoded.stamp !== undefined) {
    const ns = BigInt(decoded.stamp.seconds ?? 0) * 1000000000n + BigInt(decoded.stamp.nanos ?? 0);
    check(ns === msg.logTime, `${channel.topic} #${msg.sequence}: stamp ${ns} != log time ${msg.logTime}`);
  }
  if (ordered) {
    check(msg.logTime >= lastLogTime, `${channel.topic} #${msg.sequence}: log time goes back`);
    lastLogTime = msg.logTime;
  }
}

function describe(schemas, channels) {
  return {
    schemas: [...schemas.values()].map((s) => ({ id: s.id, name: s.name, encoding: s.encoding, bytes: s.data.length })),
    channels: [...channels.values()].map((c) => ({
      id: c.id, topic: c.topic, schema_id: c.schemaId, message_encoding: c.messageEncoding,
      metadata: Object.fromEntries(c.metadata),
    })),
  };
}

const decompressHandlers = await loadDecompressHandlers();
const result = { file: args.file };

if (!args.truncated) {
  const handle = await open(args.file, 'r');
  try {
    const reader = await McapIndexedReader.Initialize({ readable: new FileHandleReadable(handle), decompressHandlers });
    result.mode = 'indexed';
    result.library = reader.header.library;
    Object.assign(result, describe(reader.schemasById, reader.channelsById));
    result.chunks = reader.chunkIndexes.length;
    for await (const msg of reader.readMessages({ validateCrcs: true })) {
      const channel = reader.channelsById.get(msg.channelId);
      onMessage(channel, reader.schemasById.get(channel.schemaId), msg, true);
    }
    // Per topic and backwards: the reader then goes through the Message Index records.
    for (const channel of reader.channelsById.values()) {
      let n = 0;
      let last = null;
      for await (const msg of reader.readMessages({ topics: [channel.topic], reverse: true })) {
        n += 1;
        check(last === null || msg.logTime <= last, `${channel.topic}: reverse read goes forward`);
        last = msg.logTime;
      }
      check(n === (perTopic[channel.topic] ?? 0), `${channel.topic}: ${n} messages read backwards, ${perTopic[channel.topic] ?? 0} forwards`);
    }
    const stats = reader.statistics;
    check(stats !== undefined, 'no Statistics record');
    if (stats) {
      check(Number(stats.messageCount) === messages, `Statistics count ${stats.messageCount} messages, read ${messages}`);
      for (const [id, n] of stats.channelMessageCounts) {
        const topic = reader.channelsById.get(id).topic;
        check(Number(n) === (perTopic[topic] ?? 0), `Statistics count ${n} on ${topic}, read ${perTopic[topic] ?? 0}`);
      }
    }
  } finally {
    await handle.close();
  }
} else {
  // A truncated file has no footer: the indexed reader must refuse it, the streaming one reads on.
  const handle = await open(args.file, 'r');
  let indexedError = null;
  try {
    await McapIndexedReader.Initialize({ readable: new FileHandleReadable(handle), decompressHandlers });
  } catch (e) {
    indexedError = String(e.message ?? e);
  } finally {
    await handle.close();
  }
  check(indexedError !== null, 'the indexed reader accepted a file expected to be truncated');
  result.indexed_reader_error = indexedError;

  const reader = new McapStreamReader({ decompressHandlers, validateCrcs: true });
  reader.append(await readFile(args.file));
  const schemas = new Map();
  const channels = new Map();
  for (let record; (record = reader.nextRecord()) !== undefined;) {
    if (record.type === 'Header') result.library = record.library;
    else if (record.type === 'Schema') schemas.set(record.id, record);
    else if (record.type === 'Channel') channels.set(record.id, record);
    else if (record.type === 'Message') {
      const channel = channels.get(record.channelId);
      check(channel !== undefined, `message on channel ${record.channelId} before its Channel record`);
      if (channel) onMessage(channel, schemas.get(channel.schemaId), record, false);
    }
  }
  result.mode = 'stream';
  check(!reader.done(), 'the streaming reader found a complete file');
  result.unparsed_bytes = reader.bytesRemaining();
  Object.assign(result, describe(schemas, channels));
}

result.messages = messages;
result.per_topic = perTopic;
if (args.expect) {
  const report = JSON.parse(await readFile(args.expect, 'utf8'));
  const want = report.expected_per_topic;
  for (const topic of new Set([...Object.keys(want), ...Object.keys(perTopic)])) {
    check((want[topic] ?? 0) === (perTopic[topic] ?? 0), `${topic}: read ${perTopic[topic] ?? 0} messages, the writer says ${want[topic] ?? 0}`);
  }
  check(messages > 0, 'no messages read');
}
if (args.rheod) {
  const recording = JSON.parse(await readFile(args.rheod, 'utf8'));
  const want = recording.message_counts ?? {};
  for (const topic of new Set([...Object.keys(want), ...Object.keys(perTopic)])) {
    check(Number(want[topic] ?? 0) === (perTopic[topic] ?? 0), `${topic}: read ${perTopic[topic] ?? 0} messages, rheod says ${want[topic] ?? 0}`);
  }
  for (const topic of Object.keys(rheodTypes)) check(topic in perTopic, `no ${topic} channel`);
  check(rheod.badTimes.length === 0, `log times off the tick clock: ${rheod.badTimes.join('; ')}`);
  const ticks = rheod.toolTicks;
  const dropped = BigInt(recording.dropped_ticks ?? 0);
  if (ticks.length > 0) {
    // The dropped ticks are the gaps, and those after the last sample (up to last_tick).
    let gaps = 0n;
    for (let i = 1; i < ticks.length; ++i) gaps += ticks[i] - ticks[i - 1] - 1n;
    const lastTick = BigInt(recording.last_tick ?? 0);
    const trailing = lastTick - ticks[ticks.length - 1];
    check(gaps + trailing === dropped, `/tool misses ${gaps} ticks between ${ticks[0]} and ${ticks[ticks.length - 1]} and ${trailing} after; rheod dropped ${dropped}`);
    check(String(ticks[0]) === String(recording.first_tick ?? 0) && trailing >= 0n,
      `/tool spans ticks ${ticks[0]}..${ticks[ticks.length - 1]}, rheod says ${recording.first_tick}..${recording.last_tick}`);
  }
  check(rheod.tets > 0, '/scene holds no tetrahedral mesh');
  result.rheod = { tool_samples: ticks.length, dropped_ticks: Number(dropped), scene_tetrahedra: rheod.tets, scene_vertices: rheod.sceneVertices };
}
result.failures = failures;
console.log(JSON.stringify(result, null, 2));
if (failures.length > 0) {
  console.error(`read_mcap: ${failures.length} check(s) failed:\n  ${failures.slice(0, 20).join('\n  ')}`);
  process.exit(1);
}
