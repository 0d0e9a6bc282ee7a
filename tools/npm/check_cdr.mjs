// Independent check of Felt's ROS 2 CDR bytes (tests/ros2/ros2_messages_test.cc): for each case
// of the JSON file given, parse the schema text with @foxglove/rosmsg, serialise the case's value
// with @foxglove/rosmsg2-serialization and compare with Felt's bytes; then decode Felt's bytes
// with the same library and serialise the result again (it must give Felt's bytes back).
// Usage: node check_cdr.mjs CASES.json   Exit 0 when every case agrees, 1 otherwise.
import { readFileSync } from "node:fs";
import { parse } from "@foxglove/rosmsg";
import { MessageReader, MessageWriter } from "@foxglove/rosmsg2-serialization";

const cases = JSON.parse(readFileSync(process.argv[2], "utf8"));
let failures = 0;
const firstDiff = (a, b) => {
  const n = Math.min(a.length, b.length);
  for (let i = 0; i < n; i++) if (a[i] !== b[i]) return i;
  return a.length === b.length ? -1 : n;
};
for (const c of cases) {
  const felt = Buffer.from(c.hex, "hex");
  let defs;
  try {
    defs = parse(c.schema, { ros2: true });
  } catch (e) {
    console.log(`FAIL ${c.type}: schema text does not parse: ${e.message}`);
    failures++;
    continue;
  }
  const npm = Buffer.from(new MessageWriter(defs).writeMessage(c.value));
  const d = firstDiff(felt, npm);
  if (d >= 0) {
    console.log(`FAIL ${c.type} (${c.label}): bytes differ at ${d}: felt ${felt.length} bytes ` +
      `${felt.subarray(d, d + 8).toString("hex")}, npm ${npm.length} bytes ` +
      `${npm.subarray(d, d + 8).toString("hex")}`);
    failures++;
    continue;
  }
  const decoded = new MessageReader(defs).readMessage(felt);
  const again = Buffer.from(new MessageWriter(defs).writeMessage(decoded));
  if (firstDiff(felt, again) >= 0) {
    console.log(`FAIL ${c.type} (${c.label}): npm's decoding of Felt's bytes does not write them back`);
    failures++;
    continue;
  }
  console.log(`ok ${c.type} (${c.label}): ${felt.length} bytes`);
}
console.log(`${cases.length - failures} of ${cases.length} cases agree`);
process.exit(failures === 0 ? 0 : 1);
