# The firmware's C sources: the one list.
#
# Read by firmware_stm32/Makefile (command-line build), by uavarm/build/firmware.py (the host
# build of the application, which takes APP_SOURCES and GENERATED_SOURCES) and by
# tests/test_stm32_project.py, which checks that the CubeIDE project (.cproject source
# folders) builds exactly these files. Plain "NAME = path path ..." lines only, paths
# relative to firmware_stm32/.
#
# Not listed: what STM32CubeMX or STM32CubeF4 provide (HAL and CMSIS drivers, USB device
# library, system_stm32f4xx.c, startup file); the Makefile takes them from STM32CUBE_F4.

# Portable application: C99, no HAL header; builds for the host and the target.
APP_SOURCES = \
    App/Src/app.c \
    App/Src/dxl_protocol.c \
    App/Src/dxl_protocol2.c \
    App/Src/imu_mpu6050.c \
    App/Src/llcp.c \
    App/Src/motion.c \
    App/Src/servo_bus.c \
    App/Src/servo_bus2.c \
    App/Src/servo_track.c \
    App/Src/stabiliser.c

# Generated from model/manipulator.toml (make codegen); never edited by hand.
GENERATED_SOURCES = \
    ../generated/estimator.c \
    ../generated/fastmath.c \
    ../generated/filters.c \
    ../generated/kinematics.c \
    ../generated/messages.c \
    ../generated/servo_map.c

# Board logic without the HAL (ring buffers, CDC transmit queue, the servo set-up bridge's
# packet filter): host-tested.
BOARD_LOGIC_SOURCES = \
    Board/Src/byte_ring.c \
    Board/Src/cdc_link.c \
    Board/Src/servo_bridge.c

# Written against the STM32CubeF4 HAL and USB device library.
HAL_SOURCES = \
    Board/Src/board_clock.c \
    Board/Src/board_guard.c \
    Board/Src/board_port.c \
    Core/Src/main.c \
    Core/Src/stm32f4xx_hal_msp.c \
    Core/Src/stm32f4xx_it.c \
    USB_DEVICE/App/usb_device.c \
    USB_DEVICE/App/usbd_cdc_if.c \
    USB_DEVICE/App/usbd_desc.c \
    USB_DEVICE/Target/usbd_conf.c

FIRMWARE_SOURCES = $(APP_SOURCES) $(GENERATED_SOURCES) $(BOARD_LOGIC_SOURCES) $(HAL_SOURCES)

# Include folders of the above.
FIRMWARE_INCLUDES = App/Inc ../generated Board/Inc Core/Inc USB_DEVICE/App USB_DEVICE/Target
