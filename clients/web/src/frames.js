// The bridge's binary frame (docs/web.md, "Frames"): a 48-byte little-endian header, then
// 3 float32 positions and 1 float32 field value per surface vertex.

export const FIELDS = ["activation", "fiber_strain", "displacement", "region"];

export function decodeFrame(buffer) {
  const h = new DataView(buffer);
  const magic = String.fromCharCode(h.getUint8(0), h.getUint8(1), h.getUint8(2), h.getUint8(3));
  if (magic !== "FFW1") throw new Error(`not a frame (magic '${magic}')`);
  const vertices = h.getUint32(4, true);
  if (buffer.byteLength !== 48 + 16 * vertices) throw new Error(`frame of ${buffer.byteLength} bytes for ${vertices} vertices`);
  return {
    vertices,
    frame: h.getFloat64(8, true),
    time_s: h.getFloat64(16, true),
    source_ms: h.getFloat64(24, true),
    bridge_ms: h.getFloat64(32, true),
    parameter_version: h.getUint32(40, true),
    field: FIELDS[h.getUint32(44, true)],
    positions: new Float32Array(buffer, 48, 3 * vertices),
    values: new Float32Array(buffer, 48 + 12 * vertices, vertices),
    bytes: buffer.byteLength,
  };
}
