/* cffi declarations: vh_dlsim.h */
#define VH_DLSIM_MAX_TX 2
#define VH_DLSIM_N_CIS 4
typedef struct {
    vh_dlp_t plant; vh_dls_t node; vh_cambernode_t cis[4];
    uint8_t cis_on; uint8_t cis_counter; uint32_t ticks;
} vh_dlsim_t;
int vh_dlsim_set_camber(vh_dlsim_t *sim, const vh_cambernode_config_t cfg[4], int pose);
int vh_dlsim_init(vh_dlsim_t *sim, const vh_dlp_params_t *prm, uint64_t plant_seed, const vh_dls_config_t *node);
void vh_dlsim_reset(vh_dlsim_t *sim);
size_t vh_dlsim_tick(vh_dlsim_t *sim, double throttle, int gear, vh_frame_t *out, size_t cap);
size_t vh_lockstep_run(vh_dlsim_t *sim, vh_ecu_t *ecu, size_t n, const double *throttle, const uint8_t *gear,
                       vh_dlp_truth_t *truth, vh_frame_t *frames, uint32_t *frame_tick, size_t cap);
