/* Host implementation of the port interface; see host_port.h. */
#include "host_port.h"

#include <string.h>

#define HOST_MPU_INT_STATUS 0x3Au   /* MPU-6050 register map 4.16 */

static size_t fifo_push(host_fifo_t *f, const uint8_t *buf, size_t n)
{
    if (f->head > 0 && f->head + f->len + n > HOST_FIFO_CAP) {
        memmove(f->data, f->data + f->head, f->len);
        f->head = 0;
    }
    size_t room = HOST_FIFO_CAP - f->head - f->len;
    if (n > room) n = room;
    memcpy(f->data + f->head + f->len, buf, n);
    f->len += n;
    return n;
}

static size_t fifo_take(host_fifo_t *f, uint8_t *buf, size_t cap)
{
    size_t n = f->len < cap ? f->len : cap;
    memcpy(buf, f->data + f->head, n);
    f->head += n;
    f->len -= n;
    if (f->len == 0) f->head = 0;
    return n;
}

static host_port_t *hp_of(void *ctx)
{
    return (host_port_t *)ctx;
}

static uint32_t time_us(void *ctx)
{
    return hp_of(ctx)->now_us;
}

static size_t link_read(void *ctx, uint8_t *buf, size_t cap)
{
    return fifo_take(&hp_of(ctx)->link_in, buf, cap);
}

static bool link_write(void *ctx, const uint8_t *buf, size_t n)
{
    host_port_t *hp = hp_of(ctx);
    if (hp->link_refuse_writes || HOST_FIFO_CAP - hp->link_out.len < n) return false;
    return fifo_push(&hp->link_out, buf, n) == n;
}

static bool servo_busy(void *ctx)
{
    host_port_t *hp = hp_of(ctx);
    return hp->servo_tx_active && (int32_t)(hp->servo_tx_end_us - hp->now_us) > 0;
}

static bool servo_send(void *ctx, const uint8_t *buf, size_t n)
{
    host_port_t *hp = hp_of(ctx);
    if (servo_busy(ctx) || HOST_FIFO_CAP - hp->servo_out.len < n) return false;
    fifo_push(&hp->servo_out, buf, n);
    const uint64_t bits = 10u * (uint64_t)n * 1000000u;
    hp->servo_tx_end_us = hp->now_us + (uint32_t)((bits + hp->servo_baud - 1u) / hp->servo_baud);
    hp->servo_tx_active = true;
    hp->servo_sends++;
    return true;
}

static size_t servo_read(void *ctx, uint8_t *buf, size_t cap)
{
    return fifo_take(&hp_of(ctx)->servo_in, buf, cap);
}

static void servo_power(void *ctx, bool on)
{
    host_port_t *hp = hp_of(ctx);
    if (hp->servo_power != on) hp->servo_power_switches++;
    hp->servo_power = on;
}

static void led(void *ctx, uint8_t index, bool on)
{
    if (index < 2) hp_of(ctx)->led[index] = on;
}

static bool imu_read(void *ctx, uint8_t addr, uint8_t reg, uint8_t *buf, size_t n)
{
    host_port_t *hp = hp_of(ctx);
    if (!hp->imu_present || addr != hp->imu_address) return false;
    for (size_t i = 0; i < n; ++i) {
        const uint8_t r = (uint8_t)((reg + i) & 127u);
        buf[i] = hp->imu_regs[r];
        if (r == HOST_MPU_INT_STATUS) hp->imu_regs[r] &= (uint8_t)~1u;   /* DATA_RDY clears on read */
    }
    hp->imu_reads++;
    return true;
}

static bool imu_write(void *ctx, uint8_t addr, uint8_t reg, uint8_t value)
{
    host_port_t *hp = hp_of(ctx);
    if (!hp->imu_present || addr != hp->imu_address) return false;
    hp->imu_regs[reg & 127u] = value;
    hp->imu_writes++;
    return true;
}

void host_port_init(host_port_t *hp, uint32_t servo_baud, uint8_t imu_address)
{
    memset(hp, 0, sizeof *hp);
    hp->servo_baud = servo_baud;
    hp->imu_address = imu_address;
    hp->imu_present = true;
    hp->port = (port_t){
        .ctx = hp, .time_us = time_us, .link_read = link_read, .link_write = link_write,
        .servo_send = servo_send, .servo_busy = servo_busy, .servo_read = servo_read,
        .servo_power = servo_power, .led = led, .imu_read = imu_read, .imu_write = imu_write,
    };
}

size_t host_port_link_push(host_port_t *hp, const uint8_t *buf, size_t n)
{
    return fifo_push(&hp->link_in, buf, n);
}

size_t host_port_link_take(host_port_t *hp, uint8_t *buf, size_t cap)
{
    return fifo_take(&hp->link_out, buf, cap);
}

size_t host_port_servo_push(host_port_t *hp, const uint8_t *buf, size_t n)
{
    return fifo_push(&hp->servo_in, buf, n);
}

size_t host_port_servo_take(host_port_t *hp, uint8_t *buf, size_t cap)
{
    return fifo_take(&hp->servo_out, buf, cap);
}
