from setuptools import find_packages, setup

package_name = "ft_msgs_py"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    package_data={package_name: ["fastdds_udp_loopback.xml"]},
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
    ],
    install_requires=["setuptools"],
    extras_require={"test": ["pytest"]},  # colcon test runs test/ with pytest
    zip_safe=False,
    maintainer="ft-arms maintainers",
    maintainer_email="maintainers@ft-arms.org",
    description="The suite's ROS 2 interface contract in code.",
    license="Apache-2.0",
)
