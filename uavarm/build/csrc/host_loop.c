/* The main loop's quiet passes on the host; see host_loop.h. */
#include "host_loop.h"

#include <string.h>

uint32_t host_loop_arrive(host_loop_t *loop, const uint8_t *bytes, const int64_t *at_us, uint32_t n)
{
    if (loop->arriving_head > 0 && loop->arriving_head + loop->arriving_len + n > HOST_ARRIVING_CAP) {
        memmove(loop->arriving, loop->arriving + loop->arriving_head, loop->arriving_len);
        memmove(loop->arriving_us, loop->arriving_us + loop->arriving_head,
                loop->arriving_len * sizeof loop->arriving_us[0]);
        loop->arriving_head = 0;
    }
    const uint32_t room = HOST_ARRIVING_CAP - loop->arriving_head - loop->arriving_len;
    if (n > room) n = room;
    const uint32_t end = loop->arriving_head + loop->arriving_len;
    memcpy(loop->arriving + end, bytes, n);
    memcpy(loop->arriving_us + end, at_us, n * sizeof at_us[0]);
    loop->arriving_len += n;
    return n;
}

uint32_t host_loop_deliver(host_loop_t *loop, host_port_t *hp)
{
    uint32_t n = 0;
    while (n < loop->arriving_len && loop->arriving_us[loop->arriving_head + n] <= loop->now_us) n++;
    if (n == 0) return 0;
    n = (uint32_t)host_port_servo_push(hp, loop->arriving + loop->arriving_head, n);
    loop->arriving_head += n;
    loop->arriving_len -= n;
    if (loop->arriving_len == 0) loop->arriving_head = 0;
    return n;
}

uint32_t host_loop_run(host_loop_t *loop, host_port_t *hp, app_t *app)
{
    uint32_t passes = 0;
    while (loop->now_us + loop->poll_us < loop->stop_us) {
        loop->now_us += loop->poll_us;
        host_loop_deliver(loop, hp);
        if (loop->now_us >= loop->next_tick_us) {
            loop->next_tick_us += loop->tick_us;
            if (loop->tick_interrupt) app_request_tick(app);
        }
        if (!loop->clock_frozen) loop->frozen_at_us = loop->now_us;
        hp->now_us = (uint32_t)((uint64_t)loop->start_us + (uint64_t)loop->frozen_at_us);
        app_poll(app);
        app_watch(app);
        passes++;
        if (hp->servo_out.len || hp->link_out.len || hp->servo_power != loop->servo_power) break;
    }
    return passes;
}
