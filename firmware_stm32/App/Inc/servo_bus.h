/* The AX-12A servo bus: power-up, configuration and the per-tick traffic, as a
 * non-blocking state machine over the port's half-duplex UART.
 *
 *   OFF --power on--> BOOTING --boot time--> CONFIGURING --verified--> RUNNING
 *                                                 '--3 failed attempts--> FAILED
 *
 * CONFIGURING, each servo: reads what it holds (addresses 5..43), writes what differs of
 * Status Return Level 1 (answer reads only), Return Delay Time, CW/CCW Angle Limits (the joint
 * limits in servo units, so the servo itself also refuses a goal outside them), the safety
 * registers (temperature and voltage limits, Max Torque 1023, Alarm Shutdown: servo_bus.c),
 * Torque Limit 1022 (undoes an overload shutdown; one below Max Torque, which a servo that
 * lost its RAM comes back with) and Torque Enable 1 (0: sbus_power_limp), and reads it all back, with
 * the status registers (the servo's position before anything moves it). The EEPROM is
 * written only where it differs. Writes are sent whether or not the servo still answers
 * them (a servo fresh from the factory has level 2), so the driver waits for an optional
 * status packet after each one and only the read-back decides.
 *
 * RUNNING, for every sbus_command(): one broadcast SYNC_WRITE of goal position and moving
 * speed to all servos (no reply), then one READ of moving speed .. present temperature from
 * one servo, round robin, so a tick's bus time stays bounded (sbus_tick_bus_time_us()). A
 * read that times out or arrives corrupted is retried at the next command, up to
 * SBUS_READ_RETRIES times, then the servo is marked failed for this round and the next
 * servo is read. A servo read with its Torque Limit back at Max Torque has lost its RAM (a
 * supply dip resets it, torque off): one WRITE sets it up again, holding where it stands,
 * before the next READ, and it is counted (resets).
 *
 * Service: sbus_limp() turns the torque off (a broadcast WRITE) and back on (each servo set
 * up again, holding where it stands); sbus_read() reads a limp arm; sbus_power_limp() powers
 * and configures the servos with Torque Enable 0 (limp from the start).
 *
 * Received bytes are matched to the request by servo id and parameter count, so the
 * master's own echo (a single-wire UART hears itself) and stray packets are ignored. The
 * usual case, the expected status packet alone on the wire, is read straight into a buffer
 * and checked there; once a byte does not fit it, everything received for the request goes
 * through the resynchronising parser of dxl_protocol.h instead.
 *
 * X-series servos (XL430-W250, XM430-W350: Dynamixel Protocol 2.0, servo_bus2.c, built instead
 * of servo_bus.c when the model's servo.model names one) go through the same states and calls:
 * - CONFIGURING reads Return Delay Time .. Present Temperature (9..146) and writes what differs:
 *   in the EEPROM Return Delay Time, Drive Mode 0 and Operating Mode 3 (position), Temperature
 *   Limit, Max/Min Voltage Limit and PWM Limit at the model's factory values, Velocity Limit 1023 (the top
 *   of the model's speeds) with Max/Min Position Limit = the joint limits, Shutdown 0x34; the
 *   Torque Enable 0 first if it is on (the EEPROM is locked while it is on); in RAM Status Return
 *   Level 1, the status map (below), Goal PWM (the torque cap), Profile Acceleration 0 (no ramp)
 *   with Profile Velocity at the park speed, and Torque Enable 1 (0: sbus_power_limp); then reads
 *   it all back, and reads the status once through the map (where the arm is).
 * - The status map: Indirect Address 1..13 point at Torque Enable, Status Return Level, Hardware
 *   Error Status, Present Current (or Load), the low two bytes of Present Velocity (it stays
 *   within +-Velocity Limit, 1023), Present Position, the low byte of Present Input Voltage
 *   (the servos' supply limit is 16 V, 160) and Present Temperature, so one READ of Indirect
 *   Data 1..13 (224..236) gets them in 13 bytes instead of the 83 of Torque Enable .. Present
 *   Temperature (the reply's CRC and stuffing scan are the tick's largest costs on this bus;
 *   the CRCs of the tick's packets are summed from each changing byte's share, one lookup a
 *   byte: dxl2_crc_shares). The map is RAM: a servo that lost its power reads it back at
 *   its initial values, every byte 0. A servo that answers a READ has Status Return Level 1 or
 *   2, so a reading with 0 there is not the servo's state: nothing of it is taken, the map is
 *   written again (remaps) and the servo read again at once; a servo that still reads so after
 *   SBUS_READ_RETRIES is marked failed for this round, as one that does not answer.
 * - RUNNING: the SYNC_WRITE holds Profile Velocity (the speed, in 0.229 rpm) and Goal Position
 *   per servo; the status READ is the map's. A servo read with Torque Enable 0 and no hardware
 *   error has lost its RAM: it is refit (four WRITEs: Status Return Level, Goal PWM, holding
 *   where it stands, the torque on). Torque Enable 0 with Hardware Error Status set is the
 *   servo's own shutdown (it needs a REBOOT): not a reset.
 * - Replies are matched and checked as above: read straight into a buffer while every byte
 *   fits the expected status packet (header, ID, LEN, STATUS instruction, then its CRC and no
 *   FF FF FD to unstuff), else through the resynchronising parser of dxl_protocol2.h.
 * - The status error byte is last_error (bit 7 the alert: Hardware Error Status is not 0), its
 *   error number counted in error_bits[number - 1]; Hardware Error Status is hardware_error,
 *   each of its bits counted per reading in hardware_error_bits. present_speed and
 *   present_load keep the AX-12A's form (magnitude up to 1023, bit 10 for the negative
 *   direction); present_current is the register as read (XM430 Present Current in 2.69 mA,
 *   XL430 Present Load in 0.1 %); present_voltage is Present Input Voltage's low byte.
 * - The torque cap is Goal PWM (torque_limit holds it): PWM Limit (885, the factory's) in
 *   full, servo.bench_torque_limit of it on the bench (sbus_power_limp), in the configuration
 *   and in every refit; PWM Limit is written with the safety registers.
 */
#ifndef SERVO_BUS_H
#define SERVO_BUS_H

#include <stdbool.h>
#include <stdint.h>

#include "dxl_protocol.h"
#include "dxl_protocol2.h"
#include "port.h"

#ifdef __cplusplus
extern "C" {
#endif

/* cffi:begin */
#define SBUS_SERVOS 3
#define SBUS_READ_RETRIES 1
#define SBUS_CONFIG_ATTEMPTS 3
#define SBUS_STATUS_ADDR 32        /* moving speed .. present temperature: a servo that lost its */
#define SBUS_STATUS_LEN 12         /* RAM (torque limit back at Max Torque) is seen at its next reading */
#define SBUS_VERIFY_ADDR 5         /* return delay .. present temperature: the configuration */
#define SBUS_VERIFY_LEN 39         /* and the first status reading (where the arm is) */
#define SBUS_TX_MAX 48            /* the configuration's longest WRITE: the status map, 44 bytes */
#define SBUS_RX_MAX 48
#define SBUS2_STATUS_ADDR 224      /* Protocol 2.0: Indirect Data 1..13, the status map */
#define SBUS2_STATUS_LEN 13
#define SBUS2_AT_TORQUE_ENABLE 0   /* where each register stands in a status reading */
#define SBUS2_AT_STATUS_RETURN_LEVEL 1   /* (0 in a reply: the map was lost with the RAM) */
#define SBUS2_AT_HARDWARE_ERROR 2
#define SBUS2_AT_CURRENT 3         /* Present Current (XM430) or Present Load (XL430) */
#define SBUS2_AT_VELOCITY 5        /* its low 2 bytes: within +-Velocity Limit (at most 1023) */
#define SBUS2_AT_POSITION 7
#define SBUS2_AT_VOLTAGE 11        /* its low byte: the servos' supply limit is 16 V (160) */
#define SBUS2_AT_TEMPERATURE 12
#define SBUS2_VERIFY_ADDR 9        /* Return Delay Time .. Present Temperature */
#define SBUS2_VERIFY_LEN 138
#define SBUS2_SYNC_MAX 41          /* its SYNC_WRITE (never stuffed: servo_bus2.c) */
#define SBUS2_READ_LEN 14          /* a READ instruction */
#define SBUS2_RX_MAX 192           /* a verify reading (149 bytes) and room for byte stuffing */

typedef enum {
    SBUS_OFF = 0,
    SBUS_BOOTING = 1,
    SBUS_CONFIGURING = 2,
    SBUS_RUNNING = 3,
    SBUS_FAILED = 4
} sbus_state_t;

/* What the driver knows of one servo; counters wrap. */
typedef struct {
    uint8_t id;
    uint8_t last_error;            /* error byte of its latest status packet */
    bool failed;                   /* its latest read went unanswered after the retries */
    bool status_valid;             /* present_* hold a reading since power-on */
    uint16_t present_position;     /* units */
    uint16_t present_speed;        /* bit 10 = direction */
    uint16_t present_load;         /* bit 10 = direction */
    uint8_t present_voltage;       /* 0.1 V */
    uint8_t present_temperature;   /* deg C */
    uint16_t reads;                /* status readings taken */
    uint16_t timeouts;             /* requests that got no valid answer in time */
    uint16_t retries;              /* requests repeated after a timeout */
    uint16_t bad_packets;          /* status packets with a bad checksum */
    uint16_t error_packets;        /* status packets with any error bit set */
    uint16_t error_bits[7];        /* ... per bit: voltage, angle limit, overheating, range,
                                      checksum, overload, instruction */
    uint16_t resets;               /* readings with its torque off while running (a brown-out) */
    uint16_t eeprom_writes;        /* EEPROM registers written at configurations */
    /* Protocol 2.0 (X-series) only; 0 on the AX-12A */
    uint8_t hardware_error;        /* Hardware Error Status of its latest reading */
    int16_t present_current;       /* Present Current (XM430, 2.69 mA) or Present Load (XL430, 0.1 %) */
    uint16_t hardware_error_bits[8];   /* readings with each Hardware Error Status bit set */
} sbus_servo_t;

typedef struct {
    const port_t *port;
    uint32_t byte_us;              /* bus time of one byte, rounded up */
    sbus_state_t state;
    uint32_t since_us;             /* when the current state began */
    sbus_servo_t servo[SBUS_SERVOS];
    /* the transaction on the wire */
    uint8_t phase;                 /* idle, sending, awaiting a reply */
    uint8_t reply;                 /* none, optional, required */
    uint8_t expect_id;
    uint8_t expect_params;
    uint8_t expect_head[4];        /* its reply's first bytes: FF FF ID LEN */
    sbus_servo_t *expect_servo;    /* the servo asked (its id is expect_id) */
    uint32_t phase_us;
    uint32_t timeout_us;
    uint8_t tx[SBUS_TX_MAX];       /* the configuration's packets */
    uint8_t direct[DXL_STATUS_MIN_LEN + SBUS_VERIFY_LEN];   /* the expected reply so far */
    uint8_t direct_len;
    bool resync;                   /* this request's bytes go through the parser */
    const uint8_t *reply_params;   /* the accepted reply's parameters */
    uint8_t rx_buf[SBUS_RX_MAX];
    dxl_parser_t parser;
    /* configuration */
    uint8_t cfg_servo;
    uint8_t cfg_step;              /* read, write, verify */
    uint16_t cfg_mask;             /* the writes still to send */
    uint8_t cfg_attempt;
    uint8_t refit;                 /* servos found reset, to configure again (bits) */
    uint32_t resets;               /* servos found reset, in all */
    bool refitting;                /* that write is on the wire */
    uint32_t refits;
    /* running */
    bool command_pending;
    bool read_due;
    uint16_t goal[SBUS_SERVOS];
    uint16_t speed[SBUS_SERVOS];
    uint8_t sync_pkt[8 + 5 * SBUS_SERVOS];   /* the SYNC_WRITE, its constant bytes built once at init */
    uint8_t sync_len;                   /* its length, 0 if the ids cannot be sent */
    uint8_t sync_sum0;                  /* the sum of its constant bytes from ID on (checksum) */
    uint8_t read_pkt[SBUS_SERVOS][8];   /* each servo's status READ, built once at init */
    uint8_t read_index;
    uint8_t read_attempt;
    uint32_t sync_writes;
    uint32_t stray_packets;
    uint32_t status_reads;              /* readings taken, of all servos (wraps) */
    uint8_t last_read;                  /* the servo of the latest reading */
    /* service */
    bool limp;                          /* torque off on purpose (sbus_limp): no SYNC_WRITE */
    bool limp_pending;                  /* its broadcast WRITE of Torque Enable 0 is still to go */
    uint16_t torque_limit;              /* Torque Limit as configured: full, or the bench's (sbus_power_limp) */
    /* Protocol 2.0 (X-series) only (servo_bus2.c) */
    uint8_t refit_steps;                /* the refit writes still to send to servo refit_servo (bits) */
    uint8_t refit_servo;
    uint8_t remap;                      /* servos read with their status map lost, to write it again (bits) */
    bool remapping;                     /* that write is on the wire */
    uint32_t remaps;                    /* status maps written again, in all */
    uint8_t sync2_pkt[SBUS2_SYNC_MAX];  /* the SYNC_WRITE of Profile Velocity and Goal Position (head
                                           and IDs built once at init, the values per command) */
    uint8_t sync2_len;                  /* its length, 0 if the ids cannot be sent */
    uint16_t sync2_crc0;                /* its CRC with every value 0 */
    uint8_t read2_pkt[SBUS_SERVOS][SBUS2_READ_LEN];   /* each servo's status READ, built once at init */
    uint8_t read2_len[SBUS_SERVOS];     /* its length, 0 if the id cannot be sent */
    uint8_t reply2_head[SBUS_SERVOS][8];   /* the first 8 bytes of each servo's status reply, */
    uint16_t reply2_crc0[SBUS_SERVOS];     /* and the CRC of the reply with every byte after them 0 */
    const uint8_t *expect2_head;        /* the same of the reply awaited: a status reading's, */
    uint8_t other2_head[8];             /* or another's */
    uint16_t expect2_crc;               /* a status reading's reply2_crc0, another's head's CRC */
    uint8_t direct2[DXL2_STATUS_MIN_LEN + SBUS2_VERIFY_LEN];   /* the expected reply so far */
    uint8_t rx2_buf[SBUS2_RX_MAX];
    dxl2_parser_t parser2;
} sbus_t;

/* ids: the servo ids, one per joint; baud: bus speed in bit/s. */
void sbus_init(sbus_t *bus, const port_t *port, const uint8_t ids[SBUS_SERVOS], uint32_t baud);
/* Switch the servo supply; on restarts the boot and configuration, off stops all traffic. */
void sbus_power(sbus_t *bus, bool on);
/* Switch the servo supply on as sbus_power does, the servos configured with the torque off and
 * the bus limp (as after sbus_limp(true)): nothing moves them until sbus_limp(false). The bench:
 * Torque Limit MODEL_SERVO_BENCH_TORQUE_LIMIT, not the full one, until sbus_full_torque. */
void sbus_power_limp(sbus_t *bus);
/* The full Torque Limit from now on. Servos holding (RUNNING, not limp) are set up again with
 * it, holding where they stand (refit), a SYNC_WRITE still queued dropped: command nothing
 * until refit and refitting clear. Limp ones get it with their torque (sbus_limp(false)). */
void sbus_full_torque(sbus_t *bus);
/* Queue the next SYNC_WRITE (goal position and moving speed per servo, in units); ignored
 * unless RUNNING. A command not yet sent is replaced. */
void sbus_command(sbus_t *bus, const uint16_t goal[SBUS_SERVOS], const uint16_t speed[SBUS_SERVOS]);
/* Service, while RUNNING: on, one broadcast WRITE of Torque Enable 0 (the arm goes limp; the
 * supply stays on) and no SYNC_WRITE until off, which sets each servo up again as after a
 * brown-out, holding where it stands. */
void sbus_limp(sbus_t *bus, bool on);
/* Queue one status READ (round robin) without a command: how a limp arm is read. */
void sbus_read(sbus_t *bus);
/* Advance the state machine; call often (every main-loop pass). */
void sbus_poll(sbus_t *bus);
/* Worst-case bus time of one command: the SYNC_WRITE plus one status read that times out. */
uint32_t sbus_tick_bus_time_us(const sbus_t *bus);
/* cffi:end */

#ifdef __cplusplus
}
#endif

#endif /* SERVO_BUS_H */
