/* vh_insn_profile.c - a QEMU TCG plugin (host code, loaded by qemu-system-arm, never flashed): the
 * instructions executed per translation block start address, written at exit to the file named by
 * its argument out=FILE as text lines "<start address hex> <instructions>". The processor-in-the-loop
 * host maps the addresses to the image's functions (vehest_can.service.pil.profile).
 *
 * Only the few entry points of QEMU's plugin API (version 1, include/qemu/qemu-plugin.h) it uses are
 * declared here, so the build needs no QEMU headers. */
#include <inttypes.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef uint64_t qemu_plugin_id_t;
typedef struct {
    const char *target_name;
    struct {
        int min;
        int cur;
    } version;
    bool system_emulation;
    union {
        struct {
            int smp_vcpus;
            int max_vcpus;
        } system;
    };
} qemu_info_t;
struct qemu_plugin_tb;
enum qemu_plugin_op { QEMU_PLUGIN_INLINE_ADD_U64 };
typedef void (*tb_trans_cb_t)(qemu_plugin_id_t id, struct qemu_plugin_tb *tb);
typedef void (*udata_cb_t)(qemu_plugin_id_t id, void *userdata);
void qemu_plugin_register_vcpu_tb_trans_cb(qemu_plugin_id_t id, tb_trans_cb_t cb);
void qemu_plugin_register_vcpu_tb_exec_inline(struct qemu_plugin_tb *tb, enum qemu_plugin_op op, void *ptr, uint64_t imm);
size_t qemu_plugin_tb_n_insns(const struct qemu_plugin_tb *tb);
uint64_t qemu_plugin_tb_vaddr(const struct qemu_plugin_tb *tb);
void qemu_plugin_register_atexit_cb(qemu_plugin_id_t id, udata_cb_t cb, void *userdata);

#define EXPORT __attribute__((visibility("default")))
EXPORT int qemu_plugin_version = 1;

/* one record per translation (a block translated again gets another; the host sums them) */
typedef struct block {
    uint64_t vaddr;
    uint64_t insns; /* executions x the block's instructions, added inline by the generated code */
    struct block *next;
} block_t;

static block_t *blocks;
static char out_path[4096];

static void on_translate(qemu_plugin_id_t id, struct qemu_plugin_tb *tb)
{
    block_t *b = calloc(1, sizeof *b);
    (void)id;
    if (b == NULL) {
        return;
    }
    b->vaddr = qemu_plugin_tb_vaddr(tb);
    b->next = blocks;
    blocks = b; /* one vCPU: translation is serialised */
    qemu_plugin_register_vcpu_tb_exec_inline(tb, QEMU_PLUGIN_INLINE_ADD_U64, &b->insns, qemu_plugin_tb_n_insns(tb));
}

static void on_exit_(qemu_plugin_id_t id, void *p)
{
    FILE *f = fopen(out_path, "w");
    block_t *b;
    (void)id;
    (void)p;
    if (f == NULL) {
        return;
    }
    for (b = blocks; b != NULL; b = b->next) {
        if (b->insns) {
            fprintf(f, "%" PRIx64 " %" PRIu64 "\n", b->vaddr, b->insns);
        }
    }
    fclose(f);
}

EXPORT int qemu_plugin_install(qemu_plugin_id_t id, const qemu_info_t *info, int argc, char **argv)
{
    int i;
    (void)info;
    for (i = 0; i < argc; ++i) {
        if (strncmp(argv[i], "out=", 4) == 0) {
            snprintf(out_path, sizeof out_path, "%s", argv[i] + 4);
        }
    }
    if (!out_path[0]) {
        fprintf(stderr, "vh_insn_profile: needs out=FILE\n");
        return 1;
    }
    qemu_plugin_register_vcpu_tb_trans_cb(id, on_translate);
    qemu_plugin_register_atexit_cb(id, on_exit_, NULL);
    return 0;
}
