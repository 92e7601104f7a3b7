"""Instruction packets as the official DynamixelSDK (pip dynamixel-sdk) writes them: its
Protocol 1.0 packet handler on a port that keeps what it is given and answers nothing."""


class CapturePort:
    """What the SDK's packet handler needs of a port, keeping what it sends."""
    is_using = False
    baudrate = 1_000_000
    tx_time_per_byte = 0.01

    def __init__(self):
        self.sent = []

    def clearPort(self):
        pass

    def writePort(self, packet):
        self.sent.append(bytes(packet))
        return len(packet)

    def readPort(self, length):
        return []

    def getBytesAvailable(self):
        return 0

    def setPacketTimeout(self, packet_length):
        pass

    def setPacketTimeoutMillis(self, msec):
        pass

    def isPacketTimeout(self):
        return True


def sdk_packet(call: str, *args) -> bytes:
    """The bytes of one SDK call, e.g. sdk_packet("write2ByteTxOnly", 1, 30, 512)."""
    from dynamixel_sdk import PacketHandler
    port = CapturePort()
    getattr(PacketHandler(1.0), call)(port, *args)
    (packet,) = port.sent
    return packet
