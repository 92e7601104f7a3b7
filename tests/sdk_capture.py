"""Packets as the official DynamixelSDK (pip dynamixel-sdk) writes and reads them: its packet
handlers (Protocol 1.0 or 2.0) on an in-memory port that keeps what it is given and answers
with the bytes queued in it, if any."""


class CapturePort:
    """What the SDK's packet handlers need of a port: keeps what they send, serves `rx`."""
    is_using = False
    baudrate = 1_000_000
    tx_time_per_byte = 0.01

    def __init__(self, rx: bytes = b""):
        self.sent: list[bytes] = []
        self.rx = bytearray(rx)

    def clearPort(self):
        pass    # a test queues the reply before the call that reads it

    def writePort(self, packet):
        self.sent.append(bytes(packet))
        return len(packet)

    def readPort(self, length):
        out = bytes(self.rx[:length])
        del self.rx[:length]
        return out

    def getBytesAvailable(self):
        return len(self.rx)

    def setPacketTimeout(self, packet_length):
        pass

    def setPacketTimeoutMillis(self, msec):
        pass

    def isPacketTimeout(self):
        return True     # whatever is queued is all there is


def packet_handler(protocol: float):
    """The SDK's packet handler; for Protocol 2.0 with its byte stuffing put on the wire.

    Protocol2PacketHandler.txPacket calls addStuffing(txpacket) and drops the result. When
    stuffing lengthens the packet, addStuffing returns a new list and leaves txpacket as it
    was (dynamixel-sdk 4.1.0), so the SDK sends FF FF FD unstuffed, against the e-manual.
    Here addStuffing updates the caller's list instead; nothing else changes."""
    import dynamixel_sdk as sdk
    if protocol == 1.0:
        return sdk.Protocol1PacketHandler()

    class Protocol2(sdk.Protocol2PacketHandler):
        def addStuffing(self, packet):
            packet[:] = super().addStuffing(packet)
            return packet

    return Protocol2()


def sdk_packet(call: str, *args, protocol: float = 1.0) -> bytes:
    """The bytes of one SDK call, e.g. sdk_packet("write2ByteTxOnly", 1, 30, 512)."""
    port = CapturePort()
    getattr(packet_handler(protocol), call)(port, *args)
    (packet,) = port.sent
    return packet


def sdk_sync_write(handler, addr: int, data_len: int, ids, data: bytes) -> bytes:
    """The SYNC_WRITE GroupSyncWrite sends: servo ids[i] gets data[i*data_len ...]."""
    import dynamixel_sdk as sdk
    port = CapturePort()
    group = sdk.GroupSyncWrite(port, handler, addr, data_len)
    for i, id_ in enumerate(ids):
        assert group.addParam(id_, list(data[i * data_len:(i + 1) * data_len]))
    assert group.txPacket() == sdk.COMM_SUCCESS
    (packet,) = port.sent
    return packet
