#!/usr/bin/env node
// Tokenize a PBASIC source with Parallax's tokenizer (npm `pbasic-tokenizer`) and write the
// download image plus a resource report.
//
//   node tools/tokenize.js [SOURCE.bs2] [--out DIR] [--quiet]
//
// Writes DIR/<name>.json (the image: the 18-byte download packets, the 2048-byte EEPROM map,
// the resource figures) and DIR/<name>.bin (the packets back to back, as Parallax's tools send
// them). A tokenizer error prints "FILE:LINE:COL: error CODE: MESSAGE", the source line and a
// caret, and exits with status 1; nothing is written then.
'use strict';

const fs = require('fs');
const path = require('path');
const crypto = require('crypto');

const EEPROM_SIZE = 2048;
const RAM_BYTES = 26;
const PACKET_SIZE = 18;
// EEPROMFlags low two bits (PBASIC Tokenizer Library): 1 undefined data, 2 defined data, 3 program.
// Bit 7 set: the byte lies in a block that the download sends.
const FLAG_KIND = 0x03;
const FLAG_SENT = 0x80;

function usage(msg) {
  if (msg) process.stderr.write(`tokenize: error: ${msg}\n`);
  process.stderr.write('usage: node tools/tokenize.js [SOURCE.bs2] [--out DIR] [--quiet]\n');
  process.exit(2);
}

function parseArgs(argv) {
  const opts = { source: path.join(__dirname, '..', 'servobot.bs2'), out: null, quiet: false };
  let positional = 0;
  for (let i = 0; i < argv.length; i++) {
    const a = argv[i];
    if (a === '--out') {
      if (i + 1 >= argv.length) usage('--out needs a directory');
      opts.out = argv[++i];
    } else if (a === '--quiet') {
      opts.quiet = true;
    } else if (a === '-h' || a === '--help') {
      usage();
    } else if (a.startsWith('-')) {
      usage(`unknown option ${a}`);
    } else if (positional++ === 0) {
      opts.source = a;
    } else {
      usage(`unexpected argument ${a}`);
    }
  }
  if (opts.out === null) opts.out = path.join(__dirname, '..', '..', 'build');
  return opts;
}

// 1-based line and column of a character offset, and the text of that line.
function locate(source, offset) {
  const before = source.slice(0, offset);
  const line = before.split('\n').length;
  const lineStart = before.lastIndexOf('\n') + 1;
  let lineEnd = source.indexOf('\n', lineStart);
  if (lineEnd < 0) lineEnd = source.length;
  return { line, column: offset - lineStart + 1, text: source.slice(lineStart, lineEnd).replace(/\r$/, '') };
}

function errorReport(file, source, rec) {
  const err = rec.Error;
  const message = err && err.message ? err.message : String(err || 'tokenizer failed');
  const code = err && err.code !== undefined ? err.code : '?';
  const start = Math.max(0, Math.min(rec.ErrorStart || 0, source.length));
  const where = locate(source, start);
  const width = Math.max(1, rec.ErrorLength || 1);
  const caret = ' '.repeat(Math.max(0, where.column - 1)) + '^'.repeat(width);
  return `${file}:${where.line}:${where.column}: error ${code}: ${message}\n  ${where.text}\n  ${caret}\n`;
}

function resources(rec) {
  const v = rec.VarCounts;
  const bitsUsed = v.words * 16 + v.bytes * 8 + v.nibbles * 4 + v.bits;
  const flags = rec.EEPROMFlags;
  let program = 0;
  let data = 0;
  for (let i = 0; i < EEPROM_SIZE; i++) {
    const kind = flags[i] & FLAG_KIND;
    if (kind === 3) program++;
    else if (kind === 1 || kind === 2) data++;
  }
  return {
    ram: {
      bits: v.bits, nibbles: v.nibbles, bytes: v.bytes, words: v.words,
      bytes_used: Math.ceil(bitsUsed / 8), limit_bytes: RAM_BYTES,
    },
    eeprom: { program, data, free: EEPROM_SIZE - program - data, limit_bytes: EEPROM_SIZE },
  };
}

function main() {
  const opts = parseArgs(process.argv.slice(2));
  let source;
  try {
    source = fs.readFileSync(opts.source, 'latin1');
  } catch (e) {
    process.stderr.write(`tokenize: error: cannot read ${opts.source}: ${e.code || e.message}\n`);
    process.exit(2);
  }
  const pbasic = require('pbasic-tokenizer');
  const rec = pbasic.compile(source, false);
  const shown = path.relative(process.cwd(), opts.source) || opts.source;
  if (!rec.Succeeded) {
    process.stderr.write(errorReport(shown, source, rec));
    process.exit(1);
  }
  if (rec.TargetModuleName !== 'BS2') {
    process.stderr.write(`${shown}: error: target module is ${rec.TargetModuleName}, expected BS2 ({$STAMP BS2})\n`);
    process.exit(1);
  }
  const packets = [];
  for (let i = 0; i < rec.PacketCount; i++) {
    packets.push(Buffer.from(rec.PacketBuffer.slice(i * PACKET_SIZE, (i + 1) * PACKET_SIZE)));
  }
  const res = resources(rec);
  const tv = pbasic.version();
  const image = {
    format: 'servobot-image/1',
    source: path.basename(opts.source),
    source_sha256: crypto.createHash('sha256').update(Buffer.from(source, 'latin1')).digest('hex'),
    tokenizer: { package: 'pbasic-tokenizer', library_version: `${Math.floor(tv / 100)}.${String(tv % 100).padStart(2, '0')}` },
    target: rec.TargetModuleName,
    pbasic_version: rec.LanguageVersion / 100,
    resources: res,
    packet_size: PACKET_SIZE,
    packets: packets.map((p) => p.toString('hex')),
    eeprom: Buffer.from(rec.EEPROM).toString('hex'),
    eeprom_flags: Buffer.from(rec.EEPROMFlags).toString('hex'),
  };
  const base = path.basename(opts.source).replace(/\.[^.]*$/, '');
  fs.mkdirSync(opts.out, { recursive: true });
  const jsonPath = path.join(opts.out, `${base}.json`);
  const binPath = path.join(opts.out, `${base}.bin`);
  // Write to temporary names first so a failure never leaves half an image behind.
  fs.writeFileSync(`${jsonPath}.tmp`, JSON.stringify(image, null, 1) + '\n');
  fs.writeFileSync(`${binPath}.tmp`, Buffer.concat(packets));
  fs.renameSync(`${jsonPath}.tmp`, jsonPath);
  fs.renameSync(`${binPath}.tmp`, binPath);
  if (!opts.quiet) {
    const r = res.ram;
    const e = res.eeprom;
    process.stdout.write(
      `${shown}: tokenized for ${rec.TargetModuleName} (PBASIC ${image.pbasic_version}), ${packets.length} packets\n` +
      `  RAM    ${r.bytes_used} of ${r.limit_bytes} bytes (words ${r.words}, bytes ${r.bytes}, nibbles ${r.nibbles}, bits ${r.bits})\n` +
      `  EEPROM ${e.program + e.data} of ${e.limit_bytes} bytes (program ${e.program}, DATA ${e.data}, free ${e.free})\n` +
      `  wrote ${path.relative(process.cwd(), jsonPath)} and ${path.relative(process.cwd(), binPath)}\n`);
  }
}

main();
