"""A firmware status parser (dxl_protocol.h's or dxl_protocol2.h's), built through cffi,
over a buffer with guard bytes after its `size` usable ones."""


class GuardedParser:
    GUARD = 16

    def __init__(self, ffi, lib, prefix: str, size: int):
        """prefix: "dxl" (Protocol 1.0) or "dxl2" (Protocol 2.0)."""
        self.ffi, self.lib, self.size = ffi, lib, size
        self.mem = ffi.new("uint8_t[]", [0xA5] * (size + self.GUARD))
        self.p = ffi.new(f"{prefix}_parser_t *")
        self.parse_byte = getattr(lib, f"{prefix}_parse_byte")
        assert getattr(lib, f"{prefix}_parser_init")(self.p, self.mem, size) == 0

    def feed(self, data) -> list[int]:
        return [self.parse_byte(self.p, b) for b in bytes(data)]

    def packet(self):
        p = self.p
        return p.id, p.error, bytes(self.ffi.buffer(p.params, p.n_params))

    def guard_intact(self) -> bool:
        return bytes(self.ffi.buffer(self.mem + self.size, self.GUARD)) == b"\xa5" * self.GUARD

    def follow(self, stream: bytes, reference):
        """Feeds stream byte by byte; each result, and each packet reported, must be the
        reference's (an iterable of (result, packet or None) per byte)."""
        for i, (want, packet) in enumerate(reference):
            got = self.parse_byte(self.p, stream[i])
            assert got == want, (i, stream[:i + 1].hex(" "))
            if packet is not None:
                assert self.packet() == packet
        assert self.guard_intact()
