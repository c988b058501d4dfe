/* cffi declarations: vh_ecu.h */
enum { VH_ECU_DKF_T = 0, VH_ECU_DKF_S = 1, VH_ECU_N_DKF = 2 };
#define VH_ECU_MAX_TX 6
#define VH_ECU_N_GEARS 6
#define VH_ECU_N_WHEELS 4
#define VH_ECU_CAMBER_NO_RESULT 7
typedef struct {
    vh_dkf_config_t dkf[2];
    double gear_ratio[6];
    double we_min;
    uint16_t status_period_ticks;
    vh_camber_config_t camber;
    double camber_still_ww;
    uint8_t rx_burst_frames;
    vh_skf_config_t skf;
} vh_ecu_config_t;
typedef struct {
    uint16_t crc_error; uint16_t counter_repeat; uint16_t counter_skip; uint16_t dlc_error;
    uint16_t timeout; uint16_t unknown_id; uint16_t signal_invalid; uint16_t input_invalid;
    uint16_t filter_reset; uint16_t deadline_miss; uint16_t rx_burst; uint16_t saturation;
} vh_ecu_counters_t;
typedef struct { uint16_t age; uint16_t resync; uint8_t fresh; uint8_t n_tick; uint8_t timed_out; ...; } vh_ecu_rxmsg_t;
typedef struct {
    double wo; double wwl; double wwr; double to; double we; double wt;
    uint8_t valid; uint8_t gear; vh_ecu_rxmsg_t rx;
} vh_ecu_dls_t;
typedef struct {
    int16_t raw[4][3]; uint8_t present; vh_ecu_rxmsg_t rx;
    vh_camber_t cmb[4]; vh_camber_result_t last[4]; uint8_t have[4];
} vh_ecu_cis_t;
typedef struct {
    double u[13]; uint16_t valid; uint8_t heard; vh_ecu_rxmsg_t rx;
    vh_skfq_t skf; vh_ecu_counters_t cnt;
} vh_ecu_chs_t;
typedef struct {
    vh_ecu_config_t cfg;
    vh_dkf_t dkf[2];
    vh_ecu_dls_t dls;
    vh_ecu_cis_t cis;
    vh_ecu_chs_t chs;
    vh_ecu_counters_t cnt;
    double ti; uint8_t ti_valid; uint8_t gear; uint32_t tick;
    ...;
} vh_ecu_t;
void vh_ecu_config_default(vh_ecu_config_t *cfg);
int vh_ecu_init(vh_ecu_t *ecu, const vh_ecu_config_t *cfg);
void vh_ecu_reset(vh_ecu_t *ecu);
void vh_ecu_rx(vh_ecu_t *ecu, const vh_frame_t *frame);
size_t vh_ecu_step(vh_ecu_t *ecu, vh_frame_t *tx, size_t cap);
int vh_ecu_set_camber_calibration(vh_ecu_t *ecu, unsigned wheel, const vh_camber_cal_t *cal);
void vh_ecu_note_deadline_miss(vh_ecu_t *ecu, uint32_t n);
