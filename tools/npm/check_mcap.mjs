// Independent check of an MCAP file Felt wrote (tests/recordings/mcap_test.cc,
// tests/transport/mcap_recorder_test.cc): @mcap/core's stream reader (chunk CRCs checked, records
// in order, closing magic) and indexed reader (summary CRC, footer, chunk indexes; chunk CRCs
// checked as it reads), the data section CRC of DataEnd recomputed here, and every payload
// decoded with @foxglove/rosmsg2-serialization from its channel's ros2msg schema.
// Usage: node check_mcap.mjs FILE.mcap   Prints one JSON object; exit 0 when every check passed.
import { readFileSync } from "node:fs";
import { McapIndexedReader, McapStreamReader } from "@mcap/core";
import { crc32 } from "@foxglove/crc";
import { parse } from "@foxglove/rosmsg";
import { MessageReader } from "@foxglove/rosmsg2-serialization";

const file = process.argv[2];
const buf = readFileSync(file);
const out = { file, errors: [] };
const fail = (m) => out.errors.push(m);

// Chained CRC32 of one channel's payloads, in file order (Felt's test computes the same).
const chain = (prev, bytes) => {
  const b = Buffer.alloc(4 + bytes.length);
  b.writeUInt32LE(prev >>> 0, 0);
  b.set(bytes, 4);
  return crc32(b) >>> 0;
};

try {
  // 1. Stream reader: every record in file order, chunk CRCs validated.
  const stream = new McapStreamReader({ validateCrcs: true });
  stream.append(new Uint8Array(buf.buffer, buf.byteOffset, buf.byteLength));
  const schemas = new Map(), channels = new Map(), readers = new Map(), perTopic = {};
  let rec, header, dataEnd, footer, messages = 0, chunks = 0;
  while ((rec = stream.nextRecord())) {
    if (rec.type === "Header") header = rec;
    else if (rec.type === "Schema") schemas.set(rec.id, rec);
    else if (rec.type === "Channel") channels.set(rec.id, rec);
    else if (rec.type === "DataEnd") dataEnd = rec;
    else if (rec.type === "Footer") footer = rec;
    else if (rec.type === "Message") {
      messages++;
      const ch = channels.get(rec.channelId);
      const schema = schemas.get(ch.schemaId);
      if (!readers.has(ch.id)) {
        readers.set(ch.id, new MessageReader(parse(new TextDecoder().decode(schema.data), { ros2: true })));
      }
      readers.get(ch.id).readMessage(rec.data);  // throws on a payload the schema cannot decode
      const t = (perTopic[ch.topic] ??= {
        schema: schema.name, schemaEncoding: schema.encoding, messageEncoding: ch.messageEncoding,
        count: 0, crc: 0,
      });
      t.count++;
      t.crc = chain(t.crc, rec.data);
    }
  }
  if (!stream.done()) fail("stream reader did not reach the closing magic");
  out.profile = header?.profile;
  out.messages = messages;
  out.topics = perTopic;
  // 2. The data section CRC, recomputed over every byte before DataEnd.
  if (!footer || !dataEnd) fail("no Footer or DataEnd");
  else {
    const dataEndOffset = Number(footer.summaryStart) - 13;
    const crc = crc32(buf.subarray(0, dataEndOffset)) >>> 0;
    out.dataSectionCrcChecked = dataEnd.dataSectionCrc !== 0;
    if (dataEnd.dataSectionCrc !== 0 && crc !== dataEnd.dataSectionCrc) {
      fail(`data section CRC ${crc}, DataEnd says ${dataEnd.dataSectionCrc}`);
    }
  }
  // 3. Indexed reader: summary CRC and chunk indexes; every message through them.
  const readable = {
    size: async () => BigInt(buf.length),
    read: async (offset, length) => new Uint8Array(buf.buffer, buf.byteOffset + Number(offset), Number(length)),
  };
  const indexed = await McapIndexedReader.Initialize({ readable });
  out.summaryCrcChecked = footer?.summaryCrc !== 0;
  out.chunks = indexed.chunkIndexes.length;
  out.statisticsMessages = Number(indexed.statistics?.messageCount ?? -1n);
  let viaIndex = 0;
  for await (const m of indexed.readMessages({ validateCrcs: true })) { void m; viaIndex++; }
  out.indexedMessages = viaIndex;
  if (viaIndex !== messages) fail(`indexed reader found ${viaIndex} messages, stream reader ${messages}`);
  if (out.statisticsMessages !== messages) fail(`Statistics says ${out.statisticsMessages} messages, found ${messages}`);
} catch (e) {
  fail(`${e.name}: ${e.message}`);
}
out.ok = out.errors.length === 0;
console.log(JSON.stringify(out));
process.exit(out.ok ? 0 : 1);
