// Host tests of the heater control, fault detection and self-test (lib/skincontrol), driving
// skin_control_step with a simple thermal plant: each heater warms its own thermistor with a
// first-order lag, and the thermistor's count rises linearly with temperature.
#include <cmath>
#include <cstdio>
#include <cstring>
#include <vector>

#include "skin_control.h"
#include "skin_proto.h"

static int failures = 0, checks = 0;
#define CHECK(cond, ...)                                              \
    do {                                                              \
        ++checks;                                                     \
        if (!(cond)) {                                                \
            ++failures;                                               \
            std::printf("FAIL %s:%d: %s: ", __FILE__, __LINE__, #cond); \
            std::printf(__VA_ARGS__);                                 \
            std::printf("\n");                                        \
        }                                                             \
    } while (0)

struct Board {
    uint16_t n;
    std::vector<skin_heater_t> heaters;
    std::vector<uint16_t> base, strongest, counts, words;
    std::vector<int16_t> response;
    std::vector<uint8_t> sat, duty, bits;
    std::vector<double> rise;  // K above the plant's rest temperature
    std::vector<int> wiring;   // heater i warms thermistor wiring[i]
    skin_control_t c;
    double rest = 300.0;       // count at rest
    double gain = 37.0;        // counts per K
    double full = 30.0;        // K at full duty, steady state
    double tau = 5.0;          // s
    double rate = 200.0;

    explicit Board(uint16_t n_) : n(n_), heaters(n_), base(n_), strongest(n_), counts(n_),
        words(n_), response(n_), sat(n_), duty(n_), bits((n_ + 7) / 8), rise(n_), wiring(n_)
    {
        std::memset(&c, 0, sizeof c);
        c.n = n;
        c.heater = heaters.data();
        c.power_budget = 255u * n;
        c.over_temp = 3900;
        c.kp = 346;
        c.ki = 44;
        c.rate_hz = 200;
        c.st_base = base.data();
        c.st_response = response.data();
        c.st_strongest = strongest.data();
        skin_control_init(&c);
        for (uint16_t i = 0; i < n; i++)
            wiring[i] = i;
    }

    uint16_t step()
    {
        for (uint16_t i = 0; i < n; i++) {
            double v = rest + gain * rise[i];
            counts[i] = (uint16_t)std::lround(std::fmin(std::fmax(v, 0.0), 4095.0));
        }
        uint16_t flags = skin_control_step(&c, counts.data(), sat.data(), words.data(),
                                           duty.data(), bits.data());
        double a = 1.0 - std::exp(-1.0 / (rate * tau));
        for (uint16_t i = 0; i < n; i++) {
            bool on = bits[i >> 3] & (1u << (i & 7));
            int t = wiring[i];
            rise[t] += ((on ? full : 0.0) - rise[t]) * a;
        }
        return flags;
    }
};

static void test_duty_mode_sigma_delta_average()
{
    Board b(3);
    skin_control_set_duty(&b.c, 0, 0);
    skin_control_set_duty(&b.c, 1, 64);
    skin_control_set_duty(&b.c, 2, 255);
    int on[3] = {0, 0, 0};
    for (int k = 0; k < 255 * 4; k++) {
        b.step();
        for (int i = 0; i < 3; i++)
            on[i] += (b.bits[0] >> i) & 1;
    }
    CHECK(on[0] == 0, "duty 0 was on %d times", on[0]);
    CHECK(on[1] == 64 * 4, "duty 64 was on %d of 1020 samples", on[1]);
    CHECK(on[2] == 255 * 4, "duty 255 was on %d of 1020 samples", on[2]);
    CHECK(b.duty[1] == 64, "reported duty %d", b.duty[1]);
}

static void test_pi_reaches_the_setpoint_without_oscillating()
{
    Board b(2);
    uint16_t target = (uint16_t)(b.rest + b.gain * 15.0); // 15 K above rest
    skin_control_set_setpoint(&b.c, SKIN_ALL_TAXELS, target);
    int crossings = 0;
    double peak = 0;
    int prev = 0;
    for (int k = 0; k < 200 * 60; k++) {
        b.step();
        int sign = b.counts[0] > target ? 1 : -1;
        if (k > 0 && sign != prev && k > 200 * 20)
            crossings++;
        prev = sign;
        peak = std::fmax(peak, (double)b.counts[0]);
    }
    double err = std::fabs((double)b.counts[0] - target);
    CHECK(err <= 6, "count %u vs setpoint %u after 60 s", b.counts[0], target);
    CHECK(peak <= target + 0.1 * (target - b.rest), "overshoot to %.0f (setpoint %u)", peak, target);
    CHECK(b.duty[0] > 0 && b.duty[0] < 255, "duty %d at steady state", b.duty[0]);
    (void)crossings;
}

static void test_power_budget_scales_every_duty()
{
    Board b(4);
    b.c.power_budget = 2 * 255;
    skin_control_set_duty(&b.c, SKIN_ALL_TAXELS, 255);
    uint16_t flags = b.step();
    unsigned total = 0;
    for (int i = 0; i < 4; i++)
        total += b.duty[i];
    CHECK(flags & SKIN_FLAG_POWER_LIMITED, "flags 0x%x", flags);
    CHECK(total <= 2 * 255, "total duty %u over a budget of 510", total);
    CHECK(b.duty[0] == b.duty[3] && b.duty[0] >= 126, "duties %d %d", b.duty[0], b.duty[3]);
}

static void test_over_temperature_latches_until_cleared()
{
    Board b(2);
    b.c.over_temp = (uint16_t)(b.rest + b.gain * 10.0);
    skin_control_set_duty(&b.c, 0, 255);
    uint16_t flags = 0;
    int k = 0;
    for (; k < 200 * 30 && !(flags & SKIN_TAXEL_OVER_TEMPERATURE); k++)
        flags = b.step();
    CHECK(flags & SKIN_TAXEL_OVER_TEMPERATURE, "no cut-off after %d samples", k);
    CHECK(b.duty[0] == 0, "heater still at %d after the cut-off", b.duty[0]);
    CHECK((b.words[0] >> 12) & SKIN_TAXEL_OVER_TEMPERATURE, "taxel word 0x%04x", b.words[0]);
    CHECK(!((b.words[1] >> 12) & SKIN_TAXEL_OVER_TEMPERATURE), "taxel 1 flagged too");
    for (int j = 0; j < 200 * 30; j++)
        b.step(); // cooled down: still latched
    CHECK(b.duty[0] == 0 && (b.words[0] >> 12) & SKIN_TAXEL_OVER_TEMPERATURE, "unlatched by itself");
    skin_control_clear_faults(&b.c);
    b.step();
    CHECK(b.duty[0] == 255, "heater not back after CLEAR_FAULTS: %d", b.duty[0]);
}

static void test_thermistor_on_a_rail_is_a_fault_after_20_samples()
{
    Board b(2);
    skin_control_set_duty(&b.c, SKIN_ALL_TAXELS, 100);
    b.rest = 0; // open thermistor: reads 0
    b.gain = 0;
    uint16_t flags = 0;
    for (int k = 0; k < 19; k++)
        flags = b.step();
    CHECK(!(flags & SKIN_TAXEL_THERMISTOR_FAULT), "fault after 19 samples");
    flags = b.step();
    CHECK(flags & SKIN_TAXEL_THERMISTOR_FAULT, "no fault after 20 samples on the rail");
    CHECK(b.duty[0] == 0 && b.duty[1] == 0, "heaters not held off: %d %d", b.duty[0], b.duty[1]);
}

static void test_heater_fault_when_full_duty_never_reaches_the_setpoint()
{
    Board b(1);
    b.full = 0.0; // a broken heater
    skin_control_set_setpoint(&b.c, 0, 2000);
    uint16_t flags = 0;
    for (int k = 0; k < 200 * 11; k++)
        flags = b.step();
    CHECK(flags & SKIN_TAXEL_HEATER_FAULT, "no heater fault after 11 s at full duty");
}

static void test_selftest_finds_each_heater_and_a_swapped_pair()
{
    Board b(6);
    b.wiring[2] = 4; // heaters 2 and 4 wired to each other's taxel
    b.wiring[4] = 2;
    skin_control_set_duty(&b.c, SKIN_ALL_TAXELS, 40);
    CHECK(skin_control_selftest(&b.c, 9, 500, 255) == 0, "self-test refused");
    CHECK(skin_control_selftest(&b.c, 10, 500, 255) == 1, "a second self-test was accepted");
    int k = 0;
    uint16_t flags = 0;
    for (; k < 200 * 10 && !b.c.st_done; k++) {
        flags |= b.step();
        for (int i = 0; i < 6 && b.c.st_active; i++)
            CHECK(b.duty[i] == 0 || i == b.c.st_taxel, "taxel %d heated during another's pulse", i);
    }
    CHECK(b.c.st_done, "self-test did not finish");
    CHECK(flags & SKIN_FLAG_SELFTEST, "SELFTEST flag never set");
    CHECK(k >= 6 * 100 && k <= 6 * 102, "self-test took %d samples for 6 x 100", k);
    for (int i = 0; i < 6; i++) {
        int expect = (i == 2) ? 4 : (i == 4) ? 2 : i;
        CHECK(b.strongest[i] == expect, "taxel %d: strongest %u, expected %d", i, b.strongest[i], expect);
    }
    CHECK(b.response[0] > 20, "response %d", b.response[0]);
    CHECK(b.response[2] < 8, "swapped taxel 2 responded %d", b.response[2]);
    b.step();
    CHECK(b.duty[0] == 40, "duty after the self-test %d", b.duty[0]);
}

int main()
{
    test_duty_mode_sigma_delta_average();
    test_pi_reaches_the_setpoint_without_oscillating();
    test_power_budget_scales_every_duty();
    test_over_temperature_latches_until_cleared();
    test_thermistor_on_a_rail_is_a_fault_after_20_samples();
    test_heater_fault_when_full_duty_never_reaches_the_setpoint();
    test_selftest_finds_each_heater_and_a_swapped_pair();
    std::printf("control: %d checks, %d failures\n", checks, failures);
    return failures ? 1 : 0;
}
