/*
 * Start-up of the firmware on the SoC's RISC-V core (hdl/cpu.py): the core starts at address
 * 0 of its block RAM, which holds the whole image (code, read-only data and initialised data,
 * loaded with the bitstream), so nothing is copied: set the global and stack pointers, clear
 * .bss, call main. main never returns; if it did, the core would spin here.
 *
 * The initialised data are the bitstream's: a reset of the core alone (not a reload of the
 * FPGA) restarts main with the data as the last run left them. The firmware keeps its state
 * in .bss, which is cleared here, and its .data is constant in practice.
 */
    .section .text.start, "ax"
    .globl _start
_start:
    .option push
    .option norelax
    la gp, __global_pointer$
    .option pop
    la sp, __stack_top
    la a0, __bss_start
    la a1, __bss_end
1:  bgeu a0, a1, 2f
    sw zero, 0(a0)
    addi a0, a0, 4
    j 1b
2:  call main
3:  j 3b
