/* libFuzzer harness: the whole firmware application (firmware_stm32/App + generated/) on a
 * minimal in-memory board whose every input comes from the fuzzer: link bytes from the
 * drone, servo-bus replies, MPU-6050 registers (so the sample path mpu_sample ->
 * filters -> estimator -> IK is fuzzed too) and time. Built twice by fuzz/run.py: app_link
 * from the committed model file (AX-12As, Protocol 1.0), app_link_x from it made an arm of
 * XM430-W350s (Protocol 2.0: its simulated servos read through their Indirect Addresses).
 *
 * Input: a header, then operations until the input ends (missing bytes read as 0).
 *   header   start time (4 bytes, little-endian: the clock's wrap is reached too),
 *            flags (1 byte, as in OP_FLAGS)
 *   op byte  % 11 selects:
 *   0 ADVANCE s      (s & 7) picks a step from STEP_US, (s >> 3) + 1 steps: each advances
 *                    the clock, requests a tick at every 10 ms boundary (the timer
 *                    interrupt) and runs app_poll()
 *   1 FRAME k ...    one valid LLCP frame (checksum right) built from the input, then one
 *                    app_poll(): k % 6 = enable(on), engage(on), set_position from 3 raw
 *                    floats (12 bytes), set_position from 3 int8 x 1.5 mm, drone_attitude
 *                    (14 bytes), or any payload (length byte, then the bytes)
 *   2 LINK n ...     n raw link bytes, then app_poll()
 *   3 SERVO n ...    n raw bytes received on the servo bus (noise, stray packets)
 *   4 SAMPLE ...     14 bytes into the IMU's data registers ACCEL_XOUT_H .., and DATA_RDY
 *                    set in INT_STATUS (also set at every tick while PWR_MGMT_1's SLEEP
 *                    bit is clear, with gyro x's LSB toggled as noise would; a read of
 *                    INT_STATUS clears it)
 *   5 IMUREG r v     IMU register r & 127 = v (WHO_AM_I and the settings included)
 *   6 FLAGS f        bit 0: IMU absent (NACK); 1: the simulated servos answer reads and
 *                    (while their Status Return Level is 2) writes; 2: the master hears its
 *                    own bytes (single-wire echo); 3: the link's transmit queue is full;
 *                    4: replies corrupted (see CORRUPT); 5: IMU reads fail; 6: IMU writes
 *                    fail (NACK); 7: IMU writes are acknowledged but lost
 *   7 SERVOREG i a v register a % N_REGS of simulated servo i % 3 = v (present position, ...;
 *                    N_REGS 50 for the AX-12A, 252 for the X-series)
 *   8 TICK           an extra tick request (interrupt), then app_poll()
 *   9 CORRUPT k x    a corrupted reply has byte k % 16 XORed with x (x = 0: truncated
 *                    after k bytes)
 *  10 ERROR e        the simulated servos' status error byte becomes e & 0x7F
 *
 * Checked after every app_poll() and inside the port functions, besides ASan/UBSan:
 *   - every servo-bus packet the application sends is one well-formed instruction packet,
 *     sent only while the servo supply is on;
 *   - every SYNC_WRITE holds goal positions whose angles (AX-12A: 1023 units over 300 deg;
 *     X-series: 4096 a turn) are inside the joint limits, a park or working speed, and is the command of the
 *     application's joint vector q_cmd, which is safe by plain geometry (plain_arm.h:
 *     limits, body, legs, from the model file's numbers, not the generated checks) and
 *     rounds to exactly those units (the nearest inside the limits);
 *   - the servo supply is on exactly while the application is enabled, engaged implies
 *     enabled (never on the bench, enable 2, which never parks either), a usable IMU and no servo tracking fault, and after a frame "enable 0" the supply is off when app_poll() returns;
 *   - a valid frame always reaches the application (its good-frame counter moves) in the
 *     main-loop passes that drain the link input;
 *   - every link write is one valid LLCP frame of a message the board sends, of its size
 *     (heartbeat, the service streams, pong); every heartbeat's floats are finite; the
 *     commanded joints, the set position and the attitude stay finite;
 *   - the fill levels of the buffers inside app_t (servo replies, link payload) stay within
 *     them: AddressSanitizer does not see an overrun that stays inside a struct.
 *
 * With APP_LINK_TRACE set in the environment, each input ends with one line on stderr of
 * how far it got (tests/test_fuzz.py checks that the seed corpus reaches the engaged,
 * stabilising state).
 */
#include <math.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "app.h"
#include "dxl_protocol.h"
#include "dxl_protocol2.h"
#include "imu_mpu6050.h"
#include "kinematics.h"
#include "llcp.h"
#include "messages.h"
#include "model_params.h"
#include "plain_arm.h"

#define CHECK(cond) do { if (!(cond)) { __builtin_trap(); } } while (0)

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

enum { OP_ADVANCE, OP_FRAME, OP_LINK, OP_SERVO, OP_SAMPLE, OP_IMUREG, OP_FLAGS, OP_SERVOREG,
       OP_TICK, OP_CORRUPT, OP_ERROR, N_OPS };

enum { F_IMU_ABSENT = 1, F_RESPOND = 2, F_ECHO = 4, F_LINK_FULL = 8, F_CORRUPT = 16,
       F_IMU_READ_FAIL = 32, F_IMU_WRITE_FAIL = 64, F_IMU_WRITE_LOST = 128 };

static const uint32_t STEP_US[8] = { 50u, 250u, 1000u, 2500u, 10000u, 100000u, 1000000u, 0x40000000u };
#define MAX_POLLS 3000          /* bounds one input's run time */
#define N_SERVOS 3
#define FIFO_CAP 1024
/* the simulated servos' control tables: the registers the harness itself sets */
#if MODEL_DXL_PROTOCOL == 2u
#define N_REGS 252                /* .. Indirect Data 28 */
#define REG_ID 7
#define REG_RETURN_DELAY 9
#define REG_TORQUE_ENABLE 64
#define REG_STATUS_RETURN 68
#define REG_GOAL 116              /* 4 bytes */
#define REG_PRESENT 132           /* 4 bytes */
#define REG_VOLTAGE 144           /* 2 bytes */
#define REG_TEMPERATURE 146
#define REG_INDIRECT_ADDRESS 168  /* Indirect Address k at 168 + 2 (k - 1): Indirect Data k, 224 + k - 1 */
#define REG_INDIRECT_DATA 224
/* the driver's buffers (servo_bus.h) */
#define BUS_PARSER parser2
#define BUS_RX rx2_buf
#define BUS_DIRECT direct2
#define BUS_SYNC sync2_pkt
#define BUS_SYNC_LEN sync2_len
#define STATUS_MIN_LEN DXL2_STATUS_MIN_LEN
#else
#define N_REGS 50
#define REG_ID 3
#define REG_RETURN_DELAY 5
#define REG_TORQUE_ENABLE 24
#define REG_STATUS_RETURN 16
#define REG_GOAL 30               /* 2 bytes */
#define REG_PRESENT 36            /* 2 bytes */
#define REG_VOLTAGE 42            /* 1 byte */
#define REG_TEMPERATURE 43
#define BUS_PARSER parser
#define BUS_RX rx_buf
#define BUS_DIRECT direct
#define BUS_SYNC sync_pkt
#define BUS_SYNC_LEN sync_len
#define STATUS_MIN_LEN DXL_STATUS_MIN_LEN
#endif

static const uint8_t IDS[N_SERVOS] = { MODEL_SERVO1_ID, MODEL_SERVO2_ID, MODEL_SERVO3_ID };
/* float32 rounding allowed at a boundary of plain_pose_safe (rad, mm) */
#define PLAIN_SLACK 1e-4f

typedef struct {
    uint8_t data[FIFO_CAP];
    size_t len;
    size_t head;
} fifo_t;

typedef struct {
    uint32_t now;
    uint8_t flags;
    fifo_t link_in;
    fifo_t servo_in;
    bool power;
    bool tx_active;
    uint32_t tx_end;
    uint8_t regs[N_SERVOS][N_REGS];     /* the simulated servos' control tables */
    uint8_t corrupt_at;
    uint8_t corrupt_xor;
    uint8_t reply_error;
    uint8_t imu[128];
    const app_t *app;
    uint32_t sync_writes;
    uint32_t engaged_sync_writes;
    uint32_t heartbeats;
} board_t;

static board_t B;
static app_t APP;

/* ------------------------------------------------------------------ input */

typedef struct {
    const uint8_t *p;
    size_t n;
} input_t;

static uint8_t take(input_t *in)
{
    if (in->n == 0) {
        return 0;
    }
    in->n--;
    return *in->p++;
}

static void take_bytes(input_t *in, uint8_t *out, size_t n)
{
    for (size_t i = 0; i < n; ++i) {
        out[i] = take(in);
    }
}

/* ------------------------------------------------------------------ fifo */

static size_t fifo_push(fifo_t *f, const uint8_t *buf, size_t n)
{
    if (f->head > 0) {
        memmove(f->data, f->data + f->head, f->len);
        f->head = 0;
    }
    if (n > FIFO_CAP - f->len) {
        n = FIFO_CAP - f->len;
    }
    memcpy(f->data + f->len, buf, n);
    f->len += n;
    return n;
}

static size_t fifo_take(fifo_t *f, uint8_t *buf, size_t cap)
{
    size_t n = f->len < cap ? f->len : cap;
    memcpy(buf, f->data + f->head, n);
    f->head += n;
    f->len -= n;
    if (f->len == 0) {
        f->head = 0;
    }
    return n;
}

/* ------------------------------------------------------------------ checks */

static int hex_digit(uint8_t c)
{
    return c >= '0' && c <= '9' ? c - '0' : c >= 'A' && c <= 'F' ? c - 'A' + 10 : -1;
}

/* One heartbeat frame as the application wrote it to the link. Decoded here from the LLCP
 * format (llcp.h), independently of the receiver under test in llcp_rx.c. */
/* What the board may send the drone: its size, or 0 for an id it never sends. */
static size_t to_drone_size(uint8_t id)
{
    switch (id) {
    case MSG_HEARTBEAT_ID: return MSG_HEARTBEAT_SIZE;
    case MSG_IMU_RAW_ID: return MSG_IMU_RAW_SIZE;
    case MSG_SERVO_STATUS_ID: return MSG_SERVO_STATUS_SIZE;
    case MSG_PONG_ID: return MSG_PONG_SIZE;
    default: return 0;
    }
}

/* Every write to the link is one valid LLCP frame of a device -> drone message of its size
 * (the service streams and pong besides the heartbeat); a heartbeat's contents are checked. */
static void check_frame(const uint8_t *buf, size_t n)
{
    uint8_t bytes[1 + MSG_HEARTBEAT_SIZE + 1];   /* length, payload, checksum: the largest */
    uint8_t sum = 'b';
    CHECK(n >= LLCP_FRAME_SIZE(1) && n <= LLCP_FRAME_SIZE(MSG_HEARTBEAT_SIZE) && n % 2u == 1u && buf[0] == 'b');
    const size_t count = (n - 1u) / 2u;
    for (size_t i = 0; i < count; ++i) {
        const int hi = hex_digit(buf[1 + 2 * i]), lo = hex_digit(buf[2 + 2 * i]);
        CHECK(hi >= 0 && lo >= 0);
        bytes[i] = (uint8_t)(hi << 4 | lo);
        if (i + 1 < count) {
            sum = (uint8_t)(sum + buf[1 + 2 * i] + buf[2 + 2 * i]);
        }
    }
    const size_t len = count - 2u;
    CHECK(bytes[0] == len && bytes[count - 1] == sum && to_drone_size(bytes[1]) == len);
    if (bytes[1] != MSG_HEARTBEAT_ID) return;
    msg_heartbeat_t hb;
    CHECK(msg_heartbeat_unpack(bytes + 1, MSG_HEARTBEAT_SIZE, &hb));
    CHECK(isfinite(hb.set_x) && isfinite(hb.set_y) && isfinite(hb.set_z));
    CHECK(isfinite(hb.q1) && isfinite(hb.q2) && isfinite(hb.q3));
    CHECK(hb.enabled <= 2u && hb.engaged <= 1u && hb.unreachable <= 1u && hb.state <= MSG_STATE_JOGGED);
    CHECK((hb.state == MSG_STATE_OFF) == !hb.enabled);
    CHECK(!hb.engaged || hb.enabled == 1u);   /* (enabled 2, the bench: never engaged) */
    /* the bench never parks: starting, limp, or at a pose a service command asked for */
    CHECK(hb.enabled != 2u || hb.state == MSG_STATE_STARTING || hb.state >= MSG_STATE_LIMP);
    CHECK(hb.faults < (1u << MSG_FAULT_COUNT));
}

/* One SYNC_WRITE of goal position and moving speed (X-series: Profile Velocity and Goal
 * Position) to the three servos: where each entry's goal and speed stand in the packet. */
#if MODEL_DXL_PROTOCOL == 2u
#define SYNC_LEN (12u + 2u + N_SERVOS * 9u)
#define SYNC_ENTRY(pkt, i) ((pkt) + 12 + 9 * (i))
static bool sync_head_ok(const uint8_t *pkt)
{
    return pkt[4] == DXL2_BROADCAST_ID && pkt[8] == 112u && pkt[9] == 0u && pkt[10] == 8u && pkt[11] == 0u;
}
static uint32_t le(const uint8_t *p, unsigned n)
{
    uint32_t v = 0;
    for (unsigned k = n; k-- > 0;) v = v << 8 | p[k];
    return v;
}
#define ENTRY_GOAL(e) le((e) + 5, 4)
#define ENTRY_SPEED(e) le((e) + 1, 4)
#else
#define SYNC_LEN (6u + 2u + N_SERVOS * 5u)
#define SYNC_ENTRY(pkt, i) ((pkt) + 7 + 5 * (i))
static bool sync_head_ok(const uint8_t *pkt)
{
    return pkt[2] == DXL_BROADCAST_ID && pkt[5] == DXL_AX_GOAL_POSITION && pkt[6] == 4u;
}
#define ENTRY_GOAL(e) ((uint32_t)((e)[1] | (e)[2] << 8))
#define ENTRY_SPEED(e) ((uint32_t)((e)[3] | (e)[4] << 8))
#endif

static void check_sync_write(const uint8_t *pkt, size_t n)
{
    const app_t *app = B.app;
    CHECK(n == SYNC_LEN && sync_head_ok(pkt));
    CHECK(app->enabled);
    static const float lo[N_SERVOS] = ARM_JOINT_MIN_DEG, hi[N_SERVOS] = ARM_JOINT_MAX_DEG;
    CHECK(plain_pose_safe(app->q_cmd, PLAIN_SLACK));
    for (int i = 0; i < N_SERVOS; ++i) {
        const uint8_t *e = SYNC_ENTRY(pkt, i);
        CHECK(e[0] == IDS[i]);
        const float goal = (float)ENTRY_GOAL(e);
        const uint32_t speed = ENTRY_SPEED(e);
        /* the units inside the joint limits */
        const float end_a = plain_units(i, lo[i] * PLAIN_DEG), end_b = plain_units(i, hi[i] * PLAIN_DEG);
        const float first = ceilf(fminf(end_a, end_b) - 1e-3f), last = floorf(fmaxf(end_a, end_b) + 1e-3f);
        CHECK(goal >= first && goal <= last);
        CHECK(speed == MODEL_PARK_SPEED || speed == MODEL_TRANSIT_SPEED || speed == MODEL_WORKING_SPEED);
        /* the commanded joint's unit: the nearest, or the nearest inside the limits where the
         * nearest is a limit's own unit rounded outward */
        CHECK(fabsf(goal - fminf(fmaxf(plain_units(i, app->q_cmd[i]), first), last)) <= 0.5f + 1e-3f);
    }
    B.sync_writes++;
    if (app->engaged) {
        B.engaged_sync_writes++;
    }
}

/* ------------------------------------------------------------------ simulated servos */

static int servo_index(uint8_t id)
{
    for (int i = 0; i < N_SERVOS; ++i) {
        if (IDS[i] == id) {
            return i;
        }
    }
    return -1;
}

/* A corrupted reply (F_CORRUPT): byte corrupt_at % 16 XORed, or the reply cut there. */
static size_t corrupt(uint8_t *pkt, size_t len)
{
    if (B.flags & F_CORRUPT) {
        const size_t k = B.corrupt_at % 16u;
        if (B.corrupt_xor == 0) {
            len = k < len ? k : len;
        } else if (k < len) {
            pkt[k] ^= B.corrupt_xor;
        }
    }
    return len;
}

#if MODEL_DXL_PROTOCOL == 2u
/* Servo i's status packet (Protocol 2.0: stuffed, CRC-16) onto the bus. */
static void reply(int i, const uint8_t *params, size_t n)
{
    uint8_t pkt[11 + 2 * N_REGS];
    size_t len = 0;
    static const uint8_t head[] = { 0xFF, 0xFF, 0xFD, 0x00 };
    memcpy(pkt, head, sizeof head);
    pkt[4] = IDS[i];
    len = 7;
    pkt[len++] = DXL2_INST_STATUS;
    pkt[len++] = B.reply_error;
    for (size_t k = 0; k < n; ++k) {
        pkt[len++] = params[k];
        if (params[k] == 0xFD && pkt[len - 2] == 0xFF && pkt[len - 3] == 0xFF) pkt[len++] = 0xFD;   /* stuffing */
    }
    pkt[5] = (uint8_t)(len - 5u);   /* LEN: from the instruction to the CRC */
    pkt[6] = (uint8_t)((len - 5u) >> 8);
    const uint16_t crc = dxl2_crc(0, pkt, len);
    pkt[len++] = (uint8_t)crc;
    pkt[len++] = (uint8_t)(crc >> 8);
    (void)fifo_push(&B.servo_in, pkt, corrupt(pkt, len));
}

/* The address a read of register a of servo i reads: Indirect Data k's is what Indirect
 * Address k holds (itself at power-on, reading 0). */
static unsigned read_address(int i, unsigned a)
{
    if (a < REG_INDIRECT_DATA || a >= N_REGS) return a;
    const uint8_t *ia = B.regs[i] + REG_INDIRECT_ADDRESS + 2u * (a - REG_INDIRECT_DATA);
    return (unsigned)(ia[0] | ia[1] << 8);
}

/* The simulated X-series servos receive one instruction packet (well formed: checked). */
static void servos_receive(const uint8_t *pkt, size_t n)
{
    uint8_t params[DXL2_MAX_PACKET_LEN];
    size_t n_params = 0;
    for (size_t k = 8; k + 2 < n; ++k) {   /* unstuffed: the FD after each FF FF FD dropped */
        if (k >= 11 && pkt[k] == 0xFD && pkt[k - 1] == 0xFD && pkt[k - 2] == 0xFF && pkt[k - 3] == 0xFF) continue;
        params[n_params++] = pkt[k];
    }
    const uint8_t id = pkt[4], inst = pkt[7];
    if (inst == DXL2_INST_SYNC_WRITE) {
        const unsigned addr = (unsigned)(params[0] | params[1] << 8), size = (unsigned)(params[2] | params[3] << 8);
        for (size_t e = 4; size > 0 && e + 1 + size <= n_params; e += 1 + size) {
            const int i = servo_index(params[e]);
            if (i >= 0 && addr + size <= N_REGS) {
                memcpy(&B.regs[i][addr], params + e + 1, size);
                memcpy(&B.regs[i][REG_PRESENT], &B.regs[i][REG_GOAL], 4);   /* instant move */
            }
        }
        return;
    }
    for (int i = 0; i < N_SERVOS; ++i) {
        if (id != IDS[i] && id != DXL2_BROADCAST_ID) continue;
        const unsigned addr = n_params >= 2 ? (unsigned)(params[0] | params[1] << 8) : N_REGS;
        if (inst == DXL2_INST_WRITE) {
            for (size_t k = 2; k < n_params && addr + k - 2 < N_REGS; ++k) B.regs[i][addr + k - 2] = params[k];
            if ((B.flags & F_RESPOND) && B.regs[i][REG_STATUS_RETURN] == 2 && id != DXL2_BROADCAST_ID) reply(i, NULL, 0);
        } else if (inst == DXL2_INST_READ && n_params == 4 && (B.flags & F_RESPOND) && B.regs[i][REG_STATUS_RETURN] >= 1) {
            uint8_t out[N_REGS] = {0};
            const unsigned len = (unsigned)(params[2] | params[3] << 8);
            for (unsigned k = 0; k < len && k < N_REGS && addr + k < N_REGS; ++k) {
                const unsigned from = read_address(i, addr + k);
                out[k] = from < N_REGS ? B.regs[i][from] : 0;
            }
            reply(i, out, len < N_REGS ? len : N_REGS);
        }
    }
}

/* One well-formed instruction packet: header, LEN, CRC; an instruction the driver sends, to a
 * servo (SYNC_WRITE and a WRITE to all: broadcast). Is it a SYNC_WRITE? */
static bool check_instruction(const uint8_t *buf, size_t n)
{
    CHECK(n >= 10 && n <= DXL2_MAX_PACKET_LEN);
    CHECK(buf[0] == 0xFF && buf[1] == 0xFF && buf[2] == 0xFD && buf[3] == 0x00);
    CHECK((size_t)(buf[5] | buf[6] << 8) == n - 7u);
    CHECK(dxl2_crc(0, buf, n - 2u) == (uint16_t)(buf[n - 2u] | buf[n - 1u] << 8));
    const uint8_t inst = buf[7];
    CHECK(inst == DXL2_INST_WRITE || inst == DXL2_INST_READ || inst == DXL2_INST_SYNC_WRITE);
    CHECK(inst == DXL2_INST_SYNC_WRITE ? buf[4] == DXL2_BROADCAST_ID
          : servo_index(buf[4]) >= 0 || (inst == DXL2_INST_WRITE && buf[4] == DXL2_BROADCAST_ID));
    return inst == DXL2_INST_SYNC_WRITE;
}

/* Power on: the RAM (Torque Enable on) back at its initial values; the shafts where they were. */
static void servos_power_on(void)
{
    for (int i = 0; i < N_SERVOS; ++i) {
        uint8_t kept[15];
        memcpy(kept, B.regs[i] + REG_PRESENT, sizeof kept);   /* Present Position .. Temperature */
        memset(B.regs[i] + REG_TORQUE_ENABLE, 0, N_REGS - REG_TORQUE_ENABLE);
        memcpy(B.regs[i] + REG_PRESENT, kept, sizeof kept);
        B.regs[i][REG_STATUS_RETURN] = 2;
        for (unsigned k = 0; k < N_REGS - REG_INDIRECT_DATA; ++k) {
            B.regs[i][REG_INDIRECT_ADDRESS + 2u * k] = (uint8_t)(REG_INDIRECT_DATA + k);
        }
    }
}
#else
static void reply(int i, const uint8_t *params, size_t n)
{
    uint8_t pkt[6 + N_REGS];
    pkt[0] = 0xFF;
    pkt[1] = 0xFF;
    pkt[2] = IDS[i];
    pkt[3] = (uint8_t)(n + 2u);
    pkt[4] = B.reply_error;
    if (n > 0) {
        memcpy(pkt + 5, params, n);
    }
    pkt[5 + n] = dxl_checksum(pkt + 2, n + 3u);
    (void)fifo_push(&B.servo_in, pkt, corrupt(pkt, n + 6u));
}

/* The simulated AX-12A servos receive one instruction packet. */
static void servos_receive(const uint8_t *pkt, size_t n)
{
    const uint8_t id = pkt[2], inst = pkt[4];
    const uint8_t *params = pkt + 5;
    const size_t n_params = n - 6u;
    if (inst == DXL_INST_SYNC_WRITE) {
        for (size_t e = 2; e + 5 <= n_params; e += 5) {
            int i = servo_index(params[e]);
            if (i >= 0) {
                memcpy(&B.regs[i][REG_GOAL], params + e + 1, 4);
                memcpy(&B.regs[i][REG_PRESENT], params + e + 1, 2);   /* instant move */
            }
        }
        return;
    }
    int i = servo_index(id);
    if (i < 0) {
        return;
    }
    if (inst == DXL_INST_WRITE && n_params >= 2) {
        for (size_t k = 1; k < n_params && params[0] + k - 1 < N_REGS; ++k) {
            B.regs[i][params[0] + k - 1] = params[k];
        }
        if ((B.flags & F_RESPOND) && B.regs[i][REG_STATUS_RETURN] == 2) {
            reply(i, NULL, 0);
        }
    } else if (inst == DXL_INST_READ && n_params == 2 && (B.flags & F_RESPOND) && B.regs[i][REG_STATUS_RETURN] >= 1) {
        uint8_t out[N_REGS] = {0};
        const size_t len = params[1] < N_REGS ? params[1] : N_REGS;
        for (size_t k = 0; k < len && params[0] + k < N_REGS; ++k) {
            out[k] = B.regs[i][params[0] + k];
        }
        reply(i, out, len);
    }
}

static bool check_instruction(const uint8_t *buf, size_t n)
{
    CHECK(n >= 6 && n <= DXL_MAX_PACKET_LEN);
    CHECK(buf[0] == 0xFF && buf[1] == 0xFF && buf[3] == n - 4u);
    CHECK(dxl_checksum(buf + 2, n - 3u) == buf[n - 1u]);
    const uint8_t inst = buf[4];
    CHECK(inst == DXL_INST_WRITE || inst == DXL_INST_READ || inst == DXL_INST_SYNC_WRITE);
    CHECK(inst == DXL_INST_SYNC_WRITE ? buf[2] == DXL_BROADCAST_ID : servo_index(buf[2]) >= 0);
    return inst == DXL_INST_SYNC_WRITE;
}

/* Power on: the servos boot with their factory settings, shafts where they were. */
static void servos_power_on(void)
{
    for (int i = 0; i < N_SERVOS; ++i) {
        B.regs[i][REG_STATUS_RETURN] = 2;      /* answer everything */
        B.regs[i][REG_TORQUE_ENABLE] = 0;      /* torque off */
    }
}
#endif

/* ------------------------------------------------------------------ port */

static uint32_t p_time_us(void *ctx)
{
    (void)ctx;
    return B.now;
}

static size_t p_link_read(void *ctx, uint8_t *buf, size_t cap)
{
    (void)ctx;
    return fifo_take(&B.link_in, buf, cap);
}

static bool p_link_write(void *ctx, const uint8_t *buf, size_t n)
{
    (void)ctx;
    CHECK(buf != NULL);
    check_frame(buf, n);
    if (n == LLCP_FRAME_SIZE(MSG_HEARTBEAT_SIZE)) B.heartbeats++;   /* the only message that long */
    return !(B.flags & F_LINK_FULL);
}

static bool p_servo_busy(void *ctx)
{
    (void)ctx;
    return B.tx_active && (int32_t)(B.tx_end - B.now) > 0;
}

static bool p_servo_send(void *ctx, const uint8_t *buf, size_t n)
{
    CHECK(B.power);
    CHECK(buf != NULL);
    const bool sync_write = check_instruction(buf, n);
    if (p_servo_busy(ctx)) {
        return false;
    }
    if (sync_write) {
        check_sync_write(buf, n);
    }
    B.tx_active = true;
    B.tx_end = B.now + (uint32_t)n * ((10u * 1000000u + MODEL_SERVO_BAUD - 1u) / MODEL_SERVO_BAUD);
    if (B.flags & F_ECHO) {
        (void)fifo_push(&B.servo_in, buf, n);
    }
    servos_receive(buf, n);
    return true;
}

static size_t p_servo_read(void *ctx, uint8_t *buf, size_t cap)
{
    (void)ctx;
    return fifo_take(&B.servo_in, buf, cap);
}

static void p_servo_power(void *ctx, bool on)
{
    (void)ctx;
    if (on && !B.power) {
        servos_power_on();
    }
    B.power = on;
}

static void p_led(void *ctx, uint8_t index, bool on)
{
    (void)ctx;
    (void)on;
    CHECK(index < 2);
}

static bool p_imu_read(void *ctx, uint8_t addr, uint8_t reg, uint8_t *buf, size_t n)
{
    (void)ctx;
    CHECK(buf != NULL && n >= 1 && n <= MPU_BURST_BYTES);
    if ((B.flags & (F_IMU_ABSENT | F_IMU_READ_FAIL)) || addr != MODEL_MPU_ADDRESS) {
        return false;
    }
    for (size_t i = 0; i < n; ++i) {
        const uint8_t r = (uint8_t)((reg + i) & 127u);
        buf[i] = B.imu[r];
        if (r == MPU_REG_INT_STATUS) {
            B.imu[r] &= (uint8_t)~MPU_INT_DATA_RDY;   /* cleared by reading it */
        }
    }
    return true;
}

static bool p_imu_write(void *ctx, uint8_t addr, uint8_t reg, uint8_t value)
{
    (void)ctx;
    if ((B.flags & (F_IMU_ABSENT | F_IMU_WRITE_FAIL)) || addr != MODEL_MPU_ADDRESS) {
        return false;
    }
    if (!(B.flags & F_IMU_WRITE_LOST)) {
        B.imu[reg & 127u] = value;
    }
    return true;
}

static const port_t PORT = {
    .ctx = &B, .time_us = p_time_us, .link_read = p_link_read, .link_write = p_link_write,
    .servo_send = p_servo_send, .servo_busy = p_servo_busy, .servo_read = p_servo_read,
    .servo_power = p_servo_power, .led = p_led, .imu_read = p_imu_read, .imu_write = p_imu_write,
};

/* ------------------------------------------------------------------ driving */

static unsigned polls;
static uint32_t next_tick;

static void poll_and_check(void)
{
    app_poll(&APP);
    app_watch(&APP);
    polls++;
    CHECK(B.power == APP.enabled);
    CHECK(!APP.engaged || (APP.enabled && !APP.bench));
    /* engaged only with an attitude and servos that follow */
    CHECK(!APP.engaged || (APP.imu_ok && APP.imu_stale < APP_IMU_STALE_TICKS));
    CHECK(!APP.engaged || !track_fault(&APP.track));
    CHECK(isfinite(APP.q_cmd[0]) && isfinite(APP.q_cmd[1]) && isfinite(APP.q_cmd[2]));
    CHECK(isfinite(APP.set_position[0]) && isfinite(APP.set_position[1]) && isfinite(APP.set_position[2]));
    CHECK(isfinite(APP.stab.attitude.roll) && isfinite(APP.stab.attitude.pitch));
    CHECK(APP.bus.state <= SBUS_FAILED);
    /* buffers inside app_t, where AddressSanitizer does not look */
    CHECK(APP.bus.BUS_PARSER.buf == APP.bus.BUS_RX && APP.bus.BUS_PARSER.size <= sizeof APP.bus.BUS_RX);
    CHECK(APP.bus.BUS_PARSER.len <= APP.bus.BUS_PARSER.size);
    CHECK(APP.bus.direct_len <= STATUS_MIN_LEN + APP.bus.expect_params
          && STATUS_MIN_LEN + APP.bus.expect_params <= sizeof APP.bus.BUS_DIRECT);
    CHECK(APP.bus.BUS_SYNC_LEN <= sizeof APP.bus.BUS_SYNC);
    CHECK(APP.link.count <= APP.link.len);
}

static void advance(uint32_t step)
{
    B.now += step;
    if ((int32_t)(B.now - next_tick) >= 0) {
        /* the chip latches a sample while awake (PWR_MGMT_1 SLEEP clear): a fuzzed SLEEP
         * bit freezes it, as a brown-out reset would */
        if (!(B.imu[MPU_REG_PWR_MGMT_1] & 0x40u)) {
            B.imu[MPU_REG_INT_STATUS] |= MPU_INT_DATA_RDY;
            B.imu[MPU_REG_ACCEL_XOUT_H + 9] ^= 1u;   /* sensor noise: gyro x's LSB */
        }
        app_request_tick(&APP);
        next_tick = step >= MODEL_TICK_US ? B.now + MODEL_TICK_US : next_tick + MODEL_TICK_US;
    }
    poll_and_check();
}

static void send_frame(const uint8_t *payload, size_t len)
{
    char frame[LLCP_FRAME_MAX];
    const size_t n = llcp_encode(payload, len, frame, sizeof frame);
    CHECK(n > 0);
    const uint32_t ok_before = APP.link.frames_ok;
    const bool fits = fifo_push(&B.link_in, (const uint8_t *)frame, n) == n;
    /* the application takes at most APP_LINK_BYTES_PER_POLL link bytes per pass: the
     * passes that drain what was queued before the frame and the frame itself, with no
     * time passing (a real main loop passes every few microseconds) */
    do {
        poll_and_check();
    } while (B.link_in.len > 0 && polls < MAX_POLLS);
    const int want = msg_expected_len(payload[0]);
    if (fits && B.link_in.len == 0 && want == (int)len) {
        CHECK(APP.link.frames_ok >= ok_before + 1u);   /* (earlier bytes may hold frames too) */
        if (payload[0] == MSG_ENABLE_ID && payload[1] == 0) {
            CHECK(!B.power && !APP.enabled && !APP.engaged);
        }
    }
}

static void op_frame(input_t *in)
{
    uint8_t payload[LLCP_MAX_PAYLOAD];
    size_t len;
    const uint8_t k = take(in) % 6u;
    switch (k) {
    case 0:
    case 1: {
        msg_enable_t m = { .on = take(in) };   /* (engage has the same layout) */
        len = k == 0 ? msg_enable_pack(&m, payload, sizeof payload)
                     : msg_engage_pack(&(msg_engage_t){ .on = m.on }, payload, sizeof payload);
        break;
    }
    case 2: {
        uint8_t raw[12];
        msg_set_position_t m;
        take_bytes(in, raw, sizeof raw);
        memcpy(&m.x, raw, 4);
        memcpy(&m.y, raw + 4, 4);
        memcpy(&m.z, raw + 8, 4);
        len = msg_set_position_pack(&m, payload, sizeof payload);
        break;
    }
    case 3: {
        msg_set_position_t m;
        m.x = (float)(int8_t)take(in) * 1.5f;
        m.y = (float)(int8_t)take(in) * 1.5f;
        m.z = (float)(int8_t)take(in) * 1.5f;
        len = msg_set_position_pack(&m, payload, sizeof payload);
        break;
    }
    case 4:
        payload[0] = MSG_DRONE_ATTITUDE_ID;
        take_bytes(in, payload + 1, MSG_DRONE_ATTITUDE_SIZE - 1);
        len = MSG_DRONE_ATTITUDE_SIZE;
        break;
    default:
        len = 1u + take(in) % LLCP_MAX_PAYLOAD;
        take_bytes(in, payload, len);
        break;
    }
    CHECK(len > 0);
    send_frame(payload, len);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    input_t in = { data, size };
    memset(&B, 0, sizeof B);
    B.app = &APP;
    uint8_t t[4];
    take_bytes(&in, t, 4);
    B.now = (uint32_t)t[0] | (uint32_t)t[1] << 8 | (uint32_t)t[2] << 16 | (uint32_t)t[3] << 24;
    B.flags = take(&in);
    /* an MPU-6050 at rest, level: +1 g on z (4 g range: 8192 LSB/g) */
    B.imu[MPU_REG_WHO_AM_I] = MPU_WHO_AM_I;
    B.imu[MPU_REG_ACCEL_XOUT_H + 4] = 0x20;
    for (int i = 0; i < N_SERVOS; ++i) {
        const uint32_t centre = (MODEL_DXL_POSITION_MAX + 1u) / 2u;   /* present position 512 or 2048 */
        B.regs[i][REG_ID] = IDS[i];
        B.regs[i][REG_RETURN_DELAY] = 250;   /* the factory's */
        B.regs[i][REG_PRESENT] = (uint8_t)centre;
        B.regs[i][REG_PRESENT + 1] = (uint8_t)(centre >> 8);
        B.regs[i][REG_VOLTAGE] = 120;        /* 12.0 V */
        B.regs[i][REG_TEMPERATURE] = 30;     /* 30 deg C */
    }
    servos_power_on();
    polls = 0;
    next_tick = B.now + MODEL_TICK_US;
    app_init(&APP, &PORT);
    CHECK(!B.power && !APP.enabled);

    while (in.n > 0 && polls < MAX_POLLS) {
        const uint8_t op = take(&in) % N_OPS;
        switch (op) {
        case OP_ADVANCE: {
            const uint8_t s = take(&in);
            const unsigned count = (s >> 3) + 1u;
            for (unsigned i = 0; i < count && polls < MAX_POLLS; ++i) {
                advance(STEP_US[s & 7u]);
            }
            break;
        }
        case OP_FRAME:
            op_frame(&in);
            break;
        case OP_LINK: {
            uint8_t buf[256];
            const size_t n = take(&in);
            take_bytes(&in, buf, n);
            (void)fifo_push(&B.link_in, buf, n);
            poll_and_check();
            break;
        }
        case OP_SERVO: {
            uint8_t buf[256];
            const size_t n = take(&in);
            take_bytes(&in, buf, n);
            (void)fifo_push(&B.servo_in, buf, n);
            break;
        }
        case OP_SAMPLE:
            take_bytes(&in, B.imu + MPU_REG_ACCEL_XOUT_H, MPU_SAMPLE_BYTES);
            B.imu[MPU_REG_INT_STATUS] |= MPU_INT_DATA_RDY;
            break;
        case OP_IMUREG: {
            const uint8_t r = take(&in);
            B.imu[r & 127u] = take(&in);
            break;
        }
        case OP_FLAGS:
            B.flags = take(&in);
            break;
        case OP_SERVOREG: {
            const uint8_t i = take(&in) % N_SERVOS;
            const uint8_t a = take(&in) % N_REGS;
            B.regs[i][a] = take(&in);
            break;
        }
        case OP_TICK:
            app_request_tick(&APP);
            poll_and_check();
            break;
        case OP_CORRUPT:
            B.corrupt_at = take(&in);
            B.corrupt_xor = take(&in);
            break;
        default:
            B.reply_error = take(&in) & 0x7Fu;
            break;
        }
    }
    static int trace = -1;
    if (trace < 0) {
        trace = getenv("APP_LINK_TRACE") != NULL;
    }
    if (trace) {
        fprintf(stderr, "app_link: polls %u ticks %u sync_writes %u engaged_sync_writes %u "
                "heartbeats %u bus_state %d enabled %d engaged %d imu_ok %d faults 0x%02x "
                "resets %u remaps %u\n",
                polls, (unsigned)APP.ticks_run, (unsigned)B.sync_writes,
                (unsigned)B.engaged_sync_writes, (unsigned)B.heartbeats, (int)APP.bus.state,
                (int)APP.enabled, (int)APP.engaged, (int)APP.imu_ok, (unsigned)app_faults(&APP),
                (unsigned)APP.bus.resets, (unsigned)APP.bus.remaps);
    }
    return 0;
}
