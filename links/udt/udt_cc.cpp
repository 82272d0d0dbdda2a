// A congestion control class for libudt 4.11 (UDT_CC) with a switch: UDT's own rules
// until a connection is paced; paced, its UDT_MAXBW alone sets its pace.
//
// The lanes of an adaptive transfer are paced together, each at a share of a rate the
// sender's rate probe finds from the radio's queue and the packets the lanes send again
// (links/udt/rate_probe.py), through UDT_MAXBW. UDT's own control reads each radio loss
// as congestion and slows the lane that saw it below its share; after the cut it speeds
// up again by about 100 packets a second per second, so a lane cut near the end of a
// file, or handed a larger share there, finished alone while the radio idled. Paced, a
// connection sends what was lost again and does not slow down. (Cut as UDT cuts and
// recovering by 2 % every SYN instead, lanes at 2 % loss trailed their shares at the
// end all the same: README, Benchmarks, run V.)
//
// Unpaced, the rules are UDT's (the "DAIMD" control of the UDT specification): slow
// start to the first loss, then an increase every SYN interval scaled by the spare
// bandwidth the receiver estimates, and a decrease by 1/9 on each new congestion period.
// libudt does not export its own class (CUDTCC) to derive from, so they are restated
// here. Built by scripts/setup.sh into the virtual environment; links/udt/udt_cc.py
// loads it and falls back to libudt's own control where it is missing.

#include <udt/udt.h>
#include <udt/ccc.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdlib>

namespace {

int64_t micros() {
    using namespace std::chrono;
    return duration_cast<microseconds>(steady_clock::now().time_since_epoch()).count();
}

// UDT sequence numbers wrap at 2^31: a - b, in order.
int32_t seq_cmp(int32_t a, int32_t b) {
    return (std::abs(a - b) < 0x3FFFFFFF) ? (a - b) : (b - a);
}

int32_t seq_len(int32_t from, int32_t to) {
    return (from <= to) ? (to - from + 1) : (to - from + 0x7FFFFFFF + 2);
}

class EdgeCC : public CCC {
public:
    explicit EdgeCC(bool paced_from_start = false) : paced(paced_from_start) {}

    std::atomic<bool> paced;

    void init() override {
        interval_ = m_iSYNInterval;
        setACKTimer(interval_);  // microseconds, as libudt reads it: one ACK per SYN
        last_rc_ = micros();
        // libudt applies UDT_MAXBW from the first ACK on, and sends the opening window
        // before it as fast as it can: 16 packets from each lane as it opened, 19 ms of
        // a 10 Mbit/s radio's queue each. Paced from the start (a lane whose cap is set
        // before it sends), the manifest and one packet more go before the first ACK.
        m_dCWndSize = paced ? 2 : 16;
        m_dPktSndPeriod = 1.0;
        slow_start_ = true;
        last_ack_ = m_iSndCurrSeqNo;
        loss_ = false;
        last_dec_seq_ = m_iSndCurrSeqNo - 1;
        last_dec_period_ = 1.0;
        avg_naks_ = 0;
        naks_ = 0;
        dec_random_ = 1;
        dec_count_ = 0;
    }

    void onACK(int32_t ack) override {
        if (paced) {
            // UDT_MAXBW paces; the window only bounds what is in flight (the flow
            // window bounds it again). The first ACK ends the opening window.
            m_dCWndSize = m_dMaxCWndSize;
            slow_start_ = false;
            was_paced_ = true;
            m_dPktSndPeriod = 1.0;
            return;
        }
        if (was_paced_) {  // back to UDT's rules from what the receiver takes now
            was_paced_ = false;
            end_slow_start();
            last_dec_period_ = m_dPktSndPeriod;
        }
        const int64_t now = micros();
        if (now - last_rc_ < interval_) return;
        last_rc_ = now;
        if (slow_start_) {
            m_dCWndSize += seq_len(last_ack_, ack);
            last_ack_ = ack;
            if (m_dCWndSize > m_dMaxCWndSize) end_slow_start();
        } else {
            m_dCWndSize = m_iRcvRate / 1e6 * (m_iRTT + interval_) + 16;
        }
        if (slow_start_) return;
        if (loss_) {
            loss_ = false;
            return;
        }
        int64_t spare = static_cast<int64_t>(m_iBandwidth - 1e6 / m_dPktSndPeriod);
        if (m_dPktSndPeriod > last_dec_period_ && m_iBandwidth / 9 < spare)
            spare = m_iBandwidth / 9;
        const double least = 0.01;
        double inc = least;
        if (spare > 0)
            inc = std::max(least, std::pow(10.0, std::ceil(std::log10(
                static_cast<double>(spare) * m_iMSS * 8.0))) * 0.0000015 / m_iMSS);
        m_dPktSndPeriod = (m_dPktSndPeriod * interval_) / (m_dPktSndPeriod * inc + interval_);
    }

    void onLoss(const int32_t* losses, int) override {
        if (paced) return;  // sent again, and the rate probe reads an over-run radio
        if (slow_start_) {
            end_slow_start();
            if (m_iRcvRate > 0) return;
        }
        loss_ = true;
        if (seq_cmp(losses[0] & 0x7FFFFFFF, last_dec_seq_) > 0) {
            last_dec_period_ = m_dPktSndPeriod;
            m_dPktSndPeriod = std::ceil(m_dPktSndPeriod * 1.125);
            avg_naks_ = static_cast<int>(std::ceil(avg_naks_ * 0.875 + naks_ * 0.125));
            naks_ = 1;
            dec_count_ = 1;
            last_dec_seq_ = m_iSndCurrSeqNo;
            dec_random_ = static_cast<int>(std::ceil(avg_naks_ * (std::rand() / double(RAND_MAX))));
            if (dec_random_ < 1) dec_random_ = 1;
        } else if (dec_count_++ < 5 && 0 == (++naks_ % dec_random_)) {
            m_dPktSndPeriod = std::ceil(m_dPktSndPeriod * 1.125);
            last_dec_seq_ = m_iSndCurrSeqNo;
        }
    }

    void onTimeout() override {
        if (!paced && slow_start_) end_slow_start();
    }

private:
    void end_slow_start() {
        slow_start_ = false;
        if (m_iRcvRate > 0)
            m_dPktSndPeriod = 1e6 / m_iRcvRate;
        else
            m_dPktSndPeriod = (m_iRTT + interval_) / m_dCWndSize;
    }

    int interval_ = 10000;
    int64_t last_rc_ = 0;
    bool slow_start_ = true;
    bool was_paced_ = false;
    int32_t last_ack_ = 0;
    bool loss_ = false;
    int32_t last_dec_seq_ = 0;
    double last_dec_period_ = 1.0;
    int avg_naks_ = 0;
    int naks_ = 0;
    int dec_random_ = 1;
    int dec_count_ = 0;
};

// A connection paced from its start (a lane of a push, whose coordinator sets its cap
// before it sends anything).
class PacedCC : public EdgeCC {
public:
    PacedCC() : EdgeCC(true) {}
};

// This control of a connected socket; null when it is not connected or has another.
EdgeCC* edge_cc_of(int sock) {
    CCC* cc = nullptr;
    int size = sizeof(cc);
    if (UDT::getsockopt(sock, 0, UDT_CC, &cc, &size) != 0 || cc == nullptr) return nullptr;
    return dynamic_cast<EdgeCC*>(cc);
}

}  // namespace

extern "C" {

// Give a socket not yet bound or connected this control (connections a listener accepts
// inherit it), paced from its start (paced != 0) or on UDT's rules until told otherwise.
// 0 on success, -1 when libudt refuses.
int edge_udt_cc_install(int sock, int paced) {
    CCCFactory<EdgeCC> rules;
    CCCFactory<PacedCC> cap;
    CCCVirtualFactory* factory = paced ? static_cast<CCCVirtualFactory*>(&cap) : &rules;
    return UDT::setsockopt(sock, 0, UDT_CC, factory, sizeof(*factory)) == 0 ? 0 : -1;
}

// Pace a connected socket by UDT_MAXBW alone (on != 0) or by UDT's rules again. 0 on
// success, -1 when the socket is not connected or has another control.
int edge_udt_cc_pace(int sock, int on) {
    EdgeCC* edge = edge_cc_of(sock);
    if (edge == nullptr) return -1;
    edge->paced = on != 0;
    return 0;
}

// Whether a connected socket is paced by UDT_MAXBW alone: 1, 0, or -1 (not this control).
int edge_udt_cc_paced(int sock) {
    EdgeCC* edge = edge_cc_of(sock);
    return edge == nullptr ? -1 : (edge->paced ? 1 : 0);
}

}  // extern "C"
