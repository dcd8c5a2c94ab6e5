/*
 * A QEMU TCG plugin for `cargo xtask profile-firmware`: counts the instructions executed per
 * translation block and writes `start_address instructions executions` per block at exit, to the
 * file named by the plugin argument `out=PATH`.
 *
 * It declares the few functions of QEMU's plugin C API (version 1, QEMU 4.2 onwards, checked on
 * Debian's QEMU 7.2) that it uses, so no QEMU header is needed: `cc -shared -fPIC`. One vCPU (the
 * mps2-an386 board): the counters are plain inline adds.
 */
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef uint64_t qemu_plugin_id_t;
struct qemu_plugin_tb;
enum qemu_plugin_op { QEMU_PLUGIN_INLINE_ADD_U64 };
typedef void (*qemu_plugin_vcpu_tb_trans_cb_t)(qemu_plugin_id_t id, struct qemu_plugin_tb *tb);
typedef void (*qemu_plugin_udata_cb_t)(qemu_plugin_id_t id, void *userdata);

extern void qemu_plugin_register_vcpu_tb_trans_cb(qemu_plugin_id_t id,
                                                  qemu_plugin_vcpu_tb_trans_cb_t cb);
extern size_t qemu_plugin_tb_n_insns(const struct qemu_plugin_tb *tb);
extern uint64_t qemu_plugin_tb_vaddr(const struct qemu_plugin_tb *tb);
extern void qemu_plugin_register_vcpu_tb_exec_inline(struct qemu_plugin_tb *tb,
                                                     enum qemu_plugin_op op, void *ptr,
                                                     uint64_t imm);
extern void qemu_plugin_register_atexit_cb(qemu_plugin_id_t id, qemu_plugin_udata_cb_t cb,
                                           void *userdata);

__attribute__((visibility("default"))) int qemu_plugin_version = 1;

/* Blocks are keyed by start address and length (a block may be translated again, shorter or
 * longer); open addressing in a fixed table, far larger than a firmware's blocks. */
#define CAPACITY (1u << 20)

struct block {
    uint64_t key;
    uint64_t pc;
    uint64_t insns;
    uint64_t executions;
};

static struct block *blocks;
static char out_path[4096] = "hotblocks.txt";

static void write_counts(qemu_plugin_id_t id, void *userdata) {
    (void)id;
    (void)userdata;
    FILE *f = fopen(out_path, "w");
    if (f == NULL) {
        perror(out_path);
        return;
    }
    for (uint32_t i = 0; i < CAPACITY; i++) {
        const struct block *b = &blocks[i];
        if (b->key != 0 && b->executions != 0) {
            fprintf(f, "%llx %llu %llu\n", (unsigned long long)b->pc,
                    (unsigned long long)b->insns, (unsigned long long)b->executions);
        }
    }
    fclose(f);
}

static void on_translation(qemu_plugin_id_t id, struct qemu_plugin_tb *tb) {
    (void)id;
    uint64_t pc = qemu_plugin_tb_vaddr(tb);
    uint64_t insns = qemu_plugin_tb_n_insns(tb);
    uint64_t key = (pc ^ (insns << 40)) | (1ull << 63);
    uint32_t i = (uint32_t)((key * 0x9E3779B97F4A7C15ull) >> 44) & (CAPACITY - 1);
    for (uint32_t probes = 0; blocks[i].key != 0 && blocks[i].key != key; probes++) {
        if (probes == CAPACITY) {
            return; /* full: this block goes uncounted */
        }
        i = (i + 1) & (CAPACITY - 1);
    }
    struct block *b = &blocks[i];
    if (b->key == 0) {
        b->key = key;
        b->pc = pc;
        b->insns = insns;
    }
    qemu_plugin_register_vcpu_tb_exec_inline(tb, QEMU_PLUGIN_INLINE_ADD_U64, &b->executions, 1);
}

__attribute__((visibility("default"))) int qemu_plugin_install(qemu_plugin_id_t id,
                                                               const void *info, int argc,
                                                               char **argv) {
    (void)info;
    for (int i = 0; i < argc; i++) {
        if (strncmp(argv[i], "out=", 4) == 0) {
            snprintf(out_path, sizeof out_path, "%s", argv[i] + 4);
        }
    }
    blocks = calloc(CAPACITY, sizeof *blocks);
    if (blocks == NULL) {
        return -1;
    }
    qemu_plugin_register_vcpu_tb_trans_cb(id, on_translation);
    qemu_plugin_register_atexit_cb(id, write_counts, NULL);
    return 0;
}
