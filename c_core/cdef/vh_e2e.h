/* cffi declarations: vh_types.h, vh_e2e.h */
enum { VH_OK = 0, VH_EINVAL = -1, VH_ENOSPC = -2 };
enum { VH_FRAME_EXT = 1, VH_FRAME_FD = 2, VH_FRAME_BRS = 4 };
#define VH_FRAME_MAX_LEN 64
#define VH_TICK_US ...
typedef struct {
    uint32_t id;
    uint8_t len;
    uint8_t flags;
    uint8_t data[64];
} vh_frame_t;

uint8_t vh_crc8_j1850_update(uint8_t crc, const uint8_t *data, size_t len);
uint8_t vh_crc8_j1850(const uint8_t *data, size_t len);
uint8_t vh_e2e_p01_crc(const uint8_t *payload, size_t len, uint16_t data_id);
void vh_e2e_p01_protect(uint8_t *payload, size_t len, uint16_t data_id, uint8_t *counter);
typedef enum {
    VH_E2E_OK = 0, VH_E2E_INITIAL = 1, VH_E2E_REPEATED = 2, VH_E2E_SKIPPED = 3,
    VH_E2E_WRONG_CRC = 4, VH_E2E_BAD_LEN = 5
} vh_e2e_status_t;
typedef struct { uint8_t last_counter; uint8_t have_last; } vh_e2e_rx_t;
void vh_e2e_rx_init(vh_e2e_rx_t *rx);
vh_e2e_status_t vh_e2e_p01_check(vh_e2e_rx_t *rx, const uint8_t *payload, size_t len, uint16_t data_id);
